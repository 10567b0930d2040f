"""Speed of the prior: train steps/s, FLOPs per step (XLA cost analysis), achieved GFLOP/s next to
a matmul peak measured in the same run, and editing transitions/s (DDPM and DDIM).

    python benchmarks/prior_speed.py --target halfcheetah-medium-replay --presets cpu paper \
        [--steps 20] [--edit-transitions 20000] [--set F=V ...]
    python benchmarks/prior_speed.py --target embedding:1024x7 --presets cpu [--set horizon=5]

``embedding:DxA``: reward-free random-walk states of D features and A-d actions in 100 episodes
of 50 steps, the size of the paper's robot data (100 trajectories of 40-60 transitions of
1024-d DecisionNCE embeddings); the prior is then reward-free, as the presets make it for such data.
"""

from __future__ import annotations

import argparse
import json
import time

import jax
import numpy as np

from timing import matmul_peak, time_update
from xted.fields import apply_overrides
from xted.data import Dataset, load
from xted.diffusion.editor import EditConfig, edit_dataset
from xted.diffusion.config import PriorConfig, preset
from xted.diffusion.objective import init_train_state, make_train_step
from xted.diffusion.prior import Prior
from xted.diffusion.training import training_windows
from xted.data.normalizer import Normalizer


def embedding_data(spec: str) -> Dataset:
    state_dim, action_dim = (int(n) for n in spec.split("x"))
    rng = np.random.default_rng(0)
    episodes, steps = 100, 50
    walk = np.cumsum(rng.normal(scale=0.1, size=(episodes, steps + 1, state_dim)), axis=1).astype(np.float32)
    timeouts = np.zeros((episodes, steps), bool)
    timeouts[:, -1] = True
    return Dataset(observations=walk[:, :-1].reshape(-1, state_dim),
                   next_observations=walk[:, 1:].reshape(-1, state_dim),
                   actions=rng.uniform(-1, 1, (episodes * steps, action_dim)).astype(np.float32), rewards=None,
                   terminals=np.zeros(episodes * steps, bool), timeouts=timeouts.reshape(-1))


def step_cost(config: PriorConfig, data, repeats: int) -> dict:
    state = init_train_state(config, jax.random.key(0))
    sampler, _ = training_windows(data, Normalizer.fit(data), config)
    batch = sampler.batch(np.random.default_rng(0), config.batch_size)
    flops, seconds, final = time_update(make_train_step(config), state, batch, jax.random.key(1), repeats=repeats)
    params = sum(x.size for x in jax.tree.leaves(state.params))
    return {"params": int(params), "step_seconds": seconds, "steps_per_second": 1 / seconds,
            "gflop_per_step": flops / 1e9, "achieved_gflops": flops / seconds / 1e9, "state": final}


def edit_speed(config: PriorConfig, state, data, transitions: int) -> dict:
    source = data.select_episodes(np.arange(data.num_episodes))  # a copy
    ends = np.cumsum(source.episode_lengths())
    keep = int(np.searchsorted(ends, transitions) + 1)
    source = source.select_episodes(np.arange(min(keep, source.num_episodes)))
    prior = Prior(config=config, normalizer=Normalizer.fit(data), params=state.ema_params, return_range=(0.0, 1.0))
    out = {}
    for name, edit in (("ddpm", EditConfig()), ("ddim-10", EditConfig(sampler="ddim", sampler_steps=10))):
        # The first call on the very data timed compiles for its batch shape; the second is timed.
        start = time.perf_counter()
        edit_dataset(prior, source, edit)
        first = time.perf_counter() - start
        start = time.perf_counter()
        edit_dataset(prior, source, edit)
        seconds = time.perf_counter() - start
        out[name] = {"transitions": len(source), "seconds": seconds, "transitions_per_second": len(source) / seconds,
                     "compile_seconds": first - seconds}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--target", required=True)
    parser.add_argument("--presets", nargs="+", default=["cpu", "paper"])
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--edit-transitions", type=int, default=20_000)
    parser.add_argument("--set", dest="overrides", nargs="*", default=[])
    args = parser.parse_args()
    if args.target.startswith("embedding:"):
        data = embedding_data(args.target.removeprefix("embedding:"))
    else:
        data = load(args.target)
    peak = matmul_peak()
    print(json.dumps({"matmul_peak_gflops": peak, "devices": str(jax.devices())}), flush=True)
    for name in args.presets:
        config = preset(name, data.observation_dim, data.action_dim, rewards=data.has_rewards)
        config = apply_overrides(config, args.overrides) if name == "cpu" else config
        cost = step_cost(config, data, args.steps)
        state = cost.pop("state")
        result = {"preset": name, **cost, "fraction_of_peak": cost["achieved_gflops"] / peak}
        if args.edit_transitions:
            result["edit"] = edit_speed(config, state, data, args.edit_transitions)
        print(json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
