"""Which no-simulator score tells, per window, whether the plain edit left a source worse? And what
would each keep-or-revert rule leave, replayed in the simulator? (The study behind the guard's levers.)

    python benchmarks/guard_levers.py --env walker2d [--proxy-steps 10000] [--out benchmarks/results/guard_levers.jsonl]

With the shipped ``ENV-medium-replay-cpu`` prior and a dynamics proxy fitted to its training episodes,
per source window (the editor's tiling): the simulator one-step MAE of the source and of its plain edit
(every state replayed, at the velocity clip too) and the candidate scores: the proxy's error of the
source and of the edit, the largest |z| of the source's states under the target's normaliser, and the
prior's own denoising error of the source window at noise steps 2 and 10 (4 draws). Printed: each
score's AUC for "the edit is worse in the simulator", and the simulator MAE (and the share of windows
edited) that each rule leaves, against keeping every edit and the per-window oracle.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from scipy.stats import rankdata

from xted.analysis import ProxyConfig, fit_proxy
from xted.data import load, shipped, split_heldout
from xted.data.windows import tile_episodes
from xted.diffusion.config import EditConfig
from xted.diffusion.editor import _plan, _predict_noise, edit_dataset
from xted.diffusion.guard import window_means
from xted.diffusion.prior import load_prior
from xted.diffusion.schedule import q_sample
from xted.envs import parse_domain
from xted.envs.dynamics import dynamics_error

FIELDS = {"state": "observations", "action": "actions", "reward": "rewards"}


def auc(score: np.ndarray, label: np.ndarray) -> float | None:
    """The probability that a window where the edit is worse scores above one where it is not; None
    where every window (or none) is worse."""
    ranks, positives = rankdata(score), int(label.sum())
    negatives = len(label) - positives
    if not positives or not negatives:
        return None
    return float((ranks[label].sum() - positives * (positives + 1) / 2) / (positives * negatives))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", required=True, choices=["halfcheetah", "walker2d"])
    parser.add_argument("--gaps", nargs="+", default=["gravity", "friction", "thigh"])
    parser.add_argument("--proxy-steps", type=int, default=10_000)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()

    domain = parse_domain(args.env)
    prior = load_prior(shipped.prior_dir(f"{args.env}-medium-replay-cpu"))
    train, heldout = split_heldout(load(f"{args.env}-medium-replay"), 2)
    proxy = fit_proxy(train, ProxyConfig(steps=args.proxy_steps), progress=False)
    plain = EditConfig(guard=False)
    plan = _plan(prior, EditConfig(kappa=0.05))

    @jax.jit
    def denoising_error(x, key, t_small):
        b = x["state"].shape[0]
        t = jnp.full((b,), t_small)
        noise = {s: jax.random.normal(jax.random.fold_in(key, i), x[s].shape) for i, s in enumerate(x)}
        noised = {s: q_sample(prior.schedule, x[s], t, noise[s]).at[:, 0].set(x[s][:, 0]) for s in x}
        eps = _predict_noise(prior.params, plan, noised, t, jnp.full((b,), 0.9))
        return sum(((eps[s] - noise[s])[:, 1:] ** 2).mean((1, 2)) for s in x) / len(x)

    def simulator_errors(data):
        return dynamics_error(domain, data.observations, data.actions, data.require_next_observations(),
                              replay_states_at_clip=True).mae_per_transition

    def proxy_errors(data):
        return np.abs(proxy.predict(data.observations, data.actions) - data.require_next_observations()).mean(1)

    def window_scores(data):
        tiling = tile_episodes(data.episode_bounds(), prior.config.horizon)
        states = np.where(tiling.sequence_is_next[:, None], data.require_next_observations()[tiling.sequence_steps],
                          data.observations[tiling.sequence_steps])
        raw = {"state": states, "action": data.actions[tiling.sequence_steps],
               "reward": data.rewards[tiling.sequence_steps][:, None]}
        normalised = {s: prior.normalizer.normalize(FIELDS[s], raw[s]).astype(np.float32) for s in raw}
        windows = {s: jnp.asarray(v[tiling.window_rows]) for s, v in normalised.items()}
        scores = {f"denoising_t{t}": np.mean([np.asarray(denoising_error(windows, jax.random.key(k), t))
                                              for k in range(4)], 0) for t in (2, 10)}
        scores["z_max"] = np.abs(normalised["state"])[tiling.window_rows].max(axis=(1, 2))
        return tiling, scores

    resolution = float(proxy_errors(heldout).mean())
    _, heldout_scores = window_scores(heldout)
    print(f"{args.env}: proxy resolution (held-out target) {resolution:.3f}")
    for gap in args.gaps:
        source = load(f"{args.env}-{gap}")
        edited, _ = edit_dataset(prior, source, plain)
        tiling, scores = window_scores(source)
        steps, windows, n = tiling.transition_steps, tiling.transition_window, len(tiling.window_rows)
        per_transition = {"sim_source": simulator_errors(source), "sim_edited": simulator_errors(edited),
                          "proxy_source": proxy_errors(source), "proxy_edited": proxy_errors(edited)}
        w = {k: window_means(v[steps], windows, n) for k, v in per_transition.items()}
        worse = w["sim_edited"] > w["sim_source"]
        candidates = {"proxy_source": w["proxy_source"], "proxy_edited": w["proxy_edited"],
                      "proxy_edited - proxy_source": w["proxy_edited"] - w["proxy_source"], **scores}
        gain = w["proxy_source"] - w["proxy_edited"]
        rules = {"keep every edit (plain)": np.ones(n, bool), "oracle (the simulator's choice)": ~worse,
                 "proxy error lowered": gain > 0}
        for margin in (0.5, 1.0, 1.5):
            rules[f"gain > {margin} x resolution"] = gain > margin * resolution
            rules[f"gain > {margin} x resolution, z_max < 10"] = (gain > margin * resolution) & (scores["z_max"] < 10)
        for q in (0.9, 0.99):
            bound = np.quantile(heldout_scores["denoising_t10"], q)
            rules[f"denoising_t10 below held-out q{q}"] = scores["denoising_t10"] < bound
        row = {"env": args.env, "gap": gap, "resolution": resolution, "windows": n,
               "edit_worse_share": float(worse.mean()),
               "auc_edit_worse": {name: auc(score, worse) for name, score in candidates.items()}, "rules": {}}
        for name, keep in rules.items():
            kept = keep[windows]
            mae = np.where(kept, per_transition["sim_edited"][steps], per_transition["sim_source"][steps]).mean()
            row["rules"][name] = {"sim_mae": float(mae), "edited_share": float(keep.mean())}
        print(f"\n{args.env} {gap}: {worse.mean():.0%} of windows worse after the plain edit (simulator)")
        print("  AUC for 'edit worse': " + ", ".join(f"{k} {'-' if v is None else f'{v:.2f}'}"
                                                      for k, v in row["auc_edit_worse"].items()))
        for name, result in row["rules"].items():
            print(f"  {name:45s} sim MAE {result['sim_mae']:.3f}, {result['edited_share']:.0%} edited")
        if args.out:
            with args.out.open("a") as f:
                f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
