"""Top-level commands of ``xted`` around the prior: train one, edit source data with it, the demo."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer

from xted.analysis.config import ProxyConfig
from xted.cli.main import app
from xted.cli.options import config_options
from xted.fields import apply_overrides
from xted.diffusion.config import EditConfig, PriorConfig
from xted.errors import InputError
from xted.pipelines.bench.config import BenchConfig
from xted.resume import discard_run


@app.command()
@config_options(PriorConfig, into="prior_fields", skip=("state_dim", "action_dim"), preset_defaults=True)
def train(
    target: str = typer.Option(..., "--target", help="Target dataset (path or shipped name)."),
    out: Path = typer.Option(..., "--out", help="Prior folder; an existing one is resumed."),
    preset: str = typer.Option("cpu", "--preset",
                               help="cpu (fast, small), paper (the paper's model) or tiny (a smoke test)."),
    steps: int = typer.Option(20_000, "--steps", min=1, help="Total training steps."),
    checkpoint_every: int = typer.Option(1000, "--checkpoint-every", min=1),
    heldout_episodes: int = typer.Option(0, "--heldout-episodes", min=0,
                                         help="Leave this many random target episodes out (to measure the floor)."),
    overrides: List[str] = typer.Option([], "--set", help="Override a config field: FIELD=VALUE (repeatable)."),
    force: bool = typer.Option(False, "--force", help="Delete a previous prior in --out and start afresh."),
    prior_fields: List[str] = (),
) -> None:
    """Train the diffusion prior on target trajectories (resumable; progress, CSV log, checkpoints).

    The preset gives every field of the prior's config; an option below (or --set FIELD=VALUE) replaces one."""
    from xted.data import load, split_heldout
    from xted.diffusion.checkpoint import trained_steps
    from xted.diffusion.config import preset as make_preset
    from xted.diffusion.training import train_prior_folder

    data, _ = split_heldout(load(target), heldout_episodes)
    config = make_preset(preset, data.observation_dim, data.action_dim, rewards=data.has_rewards)
    config = apply_overrides(config, [*prior_fields, *overrides])
    if force:
        discard_run(out, ("prior.json",))
    steps_before = trained_steps(out)
    train_prior_folder(data, out, config, steps, checkpoint_every=checkpoint_every)
    if steps_before >= steps:
        typer.echo(f"prior already trained to step {steps_before} in {out} (--steps {steps}); nothing to do")
    else:
        typer.echo(f"prior trained to step {steps} in {out}")


@app.command()
@config_options(EditConfig, into="edit_fields")
def edit(
    prior: str = typer.Option(..., "--prior", help="Prior folder (xted train) or a shipped prior's name."),
    source: str = typer.Option(..., "--source", help="Source dataset (path or shipped name)."),
    out: str = typer.Option(..., "--out", help="Edited dataset; the format follows the path."),
    relabel_rewards_from: Optional[str] = typer.Option(
        None, "--relabel-rewards",
        help="Target dataset to fit a reward proxy r(s, a, s') to; it gives every edited transition its reward."),
    reward_proxy_steps: int = typer.Option(ProxyConfig.steps, "--reward-proxy-steps", min=1,
                                           help="Training steps of that proxy."),
    project_dynamics: Optional[str] = typer.Option(
        None, "--project-dynamics",
        help="Target dataset to fit a dynamics model to (the paper's proxy), or your own step function "
        "(module:function or file.py:function; docs/own_data.md); each edited state becomes --dynamics-weight "
        "x its prediction from the state before + the rest x the prior's (opt-in, beyond the paper; "
        "docs/editing.md)."),
    dynamics_proxy_steps: int = typer.Option(ProxyConfig.steps, "--dynamics-proxy-steps", min=1,
                                             help="Training steps of that dynamics model."),
    guard_target: Optional[str] = typer.Option(
        None, "--target",
        help="Target dataset to fit the guard's dynamics model to, for a prior that holds none (one trained "
        "before xted fitted it); the guard is on unless --no-guard."),
    force: bool = typer.Option(False, "--force", help="Replace an existing output."),
    allow_env_mismatch: bool = typer.Option(False, "--allow-env-mismatch",
                                            help="Edit data whose recorded env differs from the prior's."),
    as_json: bool = typer.Option(False, "--json", help="Print the edit's whole report as one JSON line."),
    edit_fields: List[str] = (),
) -> None:
    """Edit source trajectories toward the prior's (target) dynamics, guarded (docs/editing.md): an edited
    window is kept only where it is valid in the target and more consistent with it than the source's."""
    from xted.diffusion.prior import load_prior
    from xted.data import check_dimensions, formats, load
    from xted.envs import check_same_env, dataset_env
    from xted.envs.step_function import is_step_function_spec, load_step_function
    from xted.pipelines.edit import edit_source

    config = apply_overrides(EditConfig(), edit_fields)
    formats.check_writable(formats.target(out), overwrite=force)
    prior_model = load_prior(prior)
    step_function, step_spec = None, project_dynamics
    if project_dynamics is not None and is_step_function_spec(project_dynamics):
        step_function, project_dynamics = load_step_function(project_dynamics), None
    formats.check_apart(formats.target(out), {"--source": source, "--relabel-rewards": relabel_rewards_from,
                                              "--project-dynamics": project_dynamics, "--target": guard_target,
                                              "--prior": prior_model.path})
    source_data = load(source)
    reward_data = None if relabel_rewards_from is None else load(relabel_rewards_from)
    dynamics_data = None if project_dynamics is None else load(project_dynamics)
    guard_data = None if guard_target is None else load(guard_target)
    check_same_env(prior_model.env, dataset_env(source_data.metadata), f"--source {source}", allow_env_mismatch)
    for role, name, data in (("--relabel-rewards", relabel_rewards_from, reward_data),
                             ("--project-dynamics", project_dynamics, dynamics_data), ("--target", guard_target, guard_data)):
        if data is not None:
            check_dimensions(data, (source_data.observation_dim, source_data.action_dim), f"{role} {name}", "the source")
            check_same_env(prior_model.env, dataset_env(data.metadata), f"{role} {name}", allow_env_mismatch)
    edited, report = edit_source(
        prior_model, source_data, config, guard_target=guard_data, project_onto=step_function or dynamics_data,
        dynamics_proxy=ProxyConfig(steps=dynamics_proxy_steps, seed=config.seed), relabel_from=reward_data,
        reward_proxy=ProxyConfig(steps=reward_proxy_steps, seed=config.seed), progress=True)
    if reward_data is not None:
        report["rewards_relabelled_from"] = relabel_rewards_from
    if dynamics_data is not None:
        report["dynamics_projected_by_a_model_of"] = project_dynamics
    if step_function is not None:
        report["dynamics_projected_by_step_function"] = step_spec
    formats.save(edited, out, overwrite=force)
    if as_json:
        typer.echo(json.dumps({"out": out, **report}))
        return
    typer.echo(f"edited {report['transitions']} of {len(source_data)} transitions in {report['seconds']:.1f} s "
               f"(kappa {config.kappa}{', guarded' if config.guard else ''}) -> {out}")
    if report["passed_through_episodes"]:
        typer.echo(f"{report['passed_through_episodes']} episodes shorter than the prior's windows "
                   f"({prior_model.config.horizon - 1} steps) passed through unedited")
    if "guard" in report:
        typer.echo(report["guard"]["verdict"])


DEMO_PRIOR = "halfcheetah-medium-replay-cpu"
BENCH_STORE = BenchConfig.store
DEMO_HELDOUT_EPISODES = 2  # the shipped prior was trained with these episodes held out


@app.command()
def demo(
    train_prior_first: bool = typer.Option(False, "--train", help="Train the cpu-preset prior from scratch first."),
    steps: int = typer.Option(0, "--steps", min=0, help="Training steps with --train (default: the shipped prior's)."),
    out: Path = typer.Option(Path("xted-demo"), "--out", help="Folder for the demo's prior and edited data."),
    proxy_steps: int = typer.Option(ProxyConfig.steps, "--proxy-steps", min=0,
                                    help="Training steps of the learned proxy (0: skip it)."),
    gap: str = typer.Option("thigh", "--gap", help="The shipped source to edit: thigh, gravity or friction."),
    bench_store: Path = typer.Option(Path(BENCH_STORE), "--bench-store",
                                     help="Committed `xted bench` results to show beside the edit."),
    seed: int = typer.Option(0, "--seed", min=0),
) -> None:
    """Edit a shipped halfcheetah source (default 2x thigh) with the shipped prior; replay it in the simulator.

    The prior was trained on the shipped halfcheetah-medium-replay target; target, source and edited
    source are all replayed in the target simulator (the true one-step dynamics error), measured with
    the paper's learned dynamics proxy, and compared for task content (forward-velocity correlation).
    The recorded rewards are replayed too: the prior edits them as well. Then the committed lite-table
    rows of the task (`xted bench`): what IQL scores on target data alone, with the source, with the
    edited source, and with the source relabelled by the target simulator."""
    from xted.analysis import edit_report, fit_proxy, simulator_measures
    from xted.analysis.content import shift_text
    from xted.data import formats, load, shipped, split_heldout
    from xted.diffusion.config import PriorConfig
    from xted.diffusion.editor import edit_dataset
    from xted.diffusion.prior import load_prior
    from xted.diffusion.training import train_prior_folder
    from xted.envs import PAPER_GAPS, parse_domain

    if gap not in PAPER_GAPS["halfcheetah"]:
        raise InputError(f"--gap must be one of {', '.join(PAPER_GAPS['halfcheetah'])}, got {gap!r}")
    target, source = load("halfcheetah-medium-replay"), load(f"halfcheetah-{gap}")
    edited_path = out / f"halfcheetah-{gap}-edited.npz"
    prior_folder = shipped.prior_dir(DEMO_PRIOR)
    if train_prior_first:
        shipped_prior = load_prior(prior_folder)
        config = PriorConfig.from_dict({**shipped_prior.config.to_dict(), "seed": seed})
        prior_folder = out / "prior"
        train_prior_folder(split_heldout(target, DEMO_HELDOUT_EPISODES)[0], prior_folder, config, steps or shipped_prior.step)
    prior = load_prior(prior_folder)
    edited, report = edit_dataset(prior, source, EditConfig(seed=seed), progress=True)
    formats.save(edited, edited_path)
    domain = parse_domain("halfcheetah")
    factor = PAPER_GAPS["halfcheetah"][gap][gap]
    proxy = None
    training_episodes, heldout_episodes = split_heldout(target, DEMO_HELDOUT_EPISODES)
    if proxy_steps:
        proxy = fit_proxy(training_episodes, ProxyConfig(steps=proxy_steps, seed=seed))
    measured = edit_report(domain, source, edited, proxy, target=target)
    rows = [("target (medium-replay)", simulator_measures(domain, target)),
            (f"source ({factor:g}x {gap})", measured["simulator"]["source"]),
            ("edited source", measured["simulator"]["edited"])]
    typer.echo(f"prior: {prior.path} (step {prior.step}); edited {report['transitions']} transitions "
               f"in {report['seconds']:.1f} s -> {edited_path}")
    typer.echo("simulator dynamics error in the halfcheetah target domain (next state; recorded reward):")
    for name, row in rows:
        typer.echo(f"  {name:24s} MAE={row['mae']:.4f}  MSE={row['mse']:.4f}  (n={row['n']})  "
                   f"reward MAE={row['reward_mae']:.3f} bias={row['reward_bias']:+.3f}")
    typer.echo(f"edited / source MAE: {rows[2][1]['mae'] / rows[1][1]['mae']:.2f}")
    if proxy is not None:
        before, after = measured["proxy"]["source"], measured["proxy"]["edited"]
        resolution = proxy.error(heldout_episodes).mae
        typer.echo(f"learned proxy (the paper's measure, fitted to the prior's training episodes): "
                   f"source MAE={before:.4f}  edited MAE={after:.4f}  edited / source: {after / before:.2f}; "
                   f"on held-out target episodes {resolution:.4f}")
        if rows[1][1]["mae"] < 2 * resolution:
            typer.echo(f"  the {factor:g}x {gap} gap moves next states by {rows[1][1]['mae']:.2f}, less than twice "
                       f"what a model learned from this target data resolves ({resolution:.2f}): no learned edit "
                       "can lower this one-step error; the learner's score below is the judge")
    content = measured["content"]
    typer.echo("task content, forward-velocity correlation with the source: "
               f"edited {content['matched']['forward_velocity_correlation']:.2f}, "
               f"a different source episode {content['mismatched']['forward_velocity_correlation']:.2f}")
    typer.echo(f"task content against the target's: {shift_text(measured['shift'])}")
    _echo_bench_rows("halfcheetah", "medium-replay", gap, bench_store)


def _echo_bench_rows(env: str, target: str, gap: str, store: Path) -> None:
    from xted.pipelines.bench.columns import TGT, TGT_EDITED, TGT_ORACLE, TGT_SRC
    from xted.pipelines.bench.report import task_rows

    rows = task_rows(env, target, gap, (TGT, TGT_SRC, TGT_EDITED, TGT_ORACLE), str(store))
    found = [row for row in rows if row["n_seeds"]]
    if not found:
        typer.echo(f"lite table: no results for {env}-{target} x {gap} in {store} "
                   f"(`xted bench run --envs {env} --gaps {gap}` computes them)")
        return
    typer.echo(f"lite table, {env}-{target} with the {gap} source (IQL, normalised score, mean ± std over seeds; "
               f"committed in {store}, `xted bench report`):")
    for row in rows:
        shown = "not computed" if not row["n_seeds"] else f"{row['mean']:.1f} ± {row['std']:.1f} ({row['n_seeds']} seeds)"
        typer.echo(f"  {row['column']:12s} {shown}")
