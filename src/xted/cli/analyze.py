"""``xted analyze``: measure datasets against a domain's simulator."""

from __future__ import annotations

import json
from typing import List, Optional

import typer

from xted.analysis.config import ProxyConfig
from xted.diffusion.config import EditConfig
from xted.envs import parse_domain
from xted.envs.domains import KNOWN_ENVS

app = typer.Typer(help="Measure datasets: simulator dynamics error, learned proxy, task content.", no_args_is_help=True)


@app.command("dynamics")
def dynamics(
    datasets: List[str] = typer.Argument(..., help="Dataset paths or shipped names."),
    env: str = typer.Option(..., "--env", help=f"{KNOWN_ENVS}, or your own step "
                            "function as module:function or path/to/file.py:function (f(observations, actions) -> "
                            "next observations, batched; docs/own_data.md)."),
    gap: Optional[str] = typer.Option(None, "--gap", help="Domain to replay in (default: the target domain)."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Replay every transition (s, a, s') in the domain's simulator: next-state MAE and MSE, and
    how far the recorded rewards are from the domain's own (MAE, bias = recorded - replayed). A step
    function gives the next-state errors only."""
    from xted.data import load
    from xted.envs.dynamics import dataset_dynamics_error, reward_error
    from xted.envs.step_function import is_step_function_spec, load_step_function, step_function_error
    from xted.errors import InputError

    if is_step_function_spec(env):
        if gap is not None:
            raise InputError("--gap names a domain of a simulated env; a step function is its own domain")
        step = load_step_function(env)
        measure, domain_name = (lambda data: (step_function_error(step, data), None)), env
    else:
        domain = parse_domain(env, gap)
        measure, domain_name = (lambda data: (dataset_dynamics_error(domain, data), reward_error(domain, data))), domain.name
    results = []
    for name in datasets:
        error, rewards = measure(load(name))
        results.append({"path": name, **error.summary(), "reward": None if rewards is None else rewards.summary()})
    if as_json:
        print(json.dumps({"env": env, "domain": domain_name, "datasets": results}))
        return
    print(f"simulator dynamics error in {domain_name}")
    print(f"{'dataset':40s} {'n':>7s} {'excluded':>8s} {'MAE':>9s} {'MSE':>9s} {'MAE p50':>9s} {'MAE p90':>9s} "
          f"{'rew MAE':>9s} {'rew bias':>9s}")
    for row in results:
        q, reward = row["mae_quantiles"], row["reward"]
        rewards = "        -         -" if reward is None else f"{reward['mae']:9.4f} {reward['bias']:9.4f}"
        print(f"{row['path'][-40:]:40s} {row['n']:7d} {row['excluded_clipped']:8d} {row['mae']:9.4f} "
              f"{row['mse']:9.4f} {q['p50']:9.4f} {q['p90']:9.4f} {rewards}")


@app.command("validity")
def validity(
    datasets: List[str] = typer.Argument(..., help="Dataset paths or shipped names."),
    env: Optional[str] = typer.Option(None, "--env", help=f"The target env, {KNOWN_ENVS}: its "
                                                          "termination rule and action space."),
    target: Optional[str] = typer.Option(None, "--target", help="Target data: the ranges its actions and states span."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """No simulator needed: per dataset, transitions that step into a state the target env ends an
    episode on while flagged non-terminal (and the reverse), actions outside the action space, next
    states outside the range the target data spans."""
    from xted.analysis import transition_validity
    from xted.data import load

    reference = None if target is None else load(target)
    results = [{"path": name, **transition_validity(load(name), env, reference)} for name in datasets]
    if as_json:
        print(json.dumps({"env": env, "target": target, "datasets": results}))
        return
    columns = ("transitions", "unflagged_terminal", "flagged_but_healthy", "actions_outside",
               "states_outside_target_range")
    print(f"{'dataset':40s} " + " ".join(f"{c:>16.16s}" for c in columns) + "  (-: unknown without --env / --target)")
    for row in results:
        print(f"{row['path'][-40:]:40s} " + " ".join(f"{'-' if row[c] is None else row[c]:>16}" for c in columns))


@app.command("edit-plan")
def edit_plan(
    sources: List[str] = typer.Argument(..., help="Source datasets (paths or shipped names)."),
    prior: str = typer.Option(..., "--prior", help="Prior folder or a shipped prior's name."),
    target: Optional[str] = typer.Option(None, "--target",
                                         help="Target data to fit the guard's model to, for a prior that holds none."),
    kappas: str = typer.Option("0.1,0.3,0.5,0.7", "--kappas", help="Candidate kappas, comma-separated."),
    transitions: int = typer.Option(2000, "--transitions", min=1,
                                    help="Source steps sampled (whole random episodes) and edited at each kappa."),
    guard_disagreement: float = typer.Option(
        EditConfig.guard_disagreement, "--guard-disagreement",
        help="As xted edit's: a window's gain must also exceed W x the target model ensemble's disagreement on it "
        "(the prior's ensemble, or one fitted to --target)."),
    seed: int = typer.Option(0, "--seed", min=0),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Before any learner, no simulator needed: per source, the share of windows beyond the prior's
    support, its mismatch against the target model's resolution, the kappa to edit at, and whether
    the guarded edit is expected to help or keep the source as it is."""
    from xted.diffusion.prior import load_prior
    from xted.data import check_dimensions, load
    from xted.diffusion.diagnosis import diagnose_edit
    from xted.diffusion.guard import fit_for_edit
    from xted.errors import InputError

    try:
        candidates = tuple(sorted(float(k) for k in kappas.split(",")))
    except ValueError:
        raise InputError(f"--kappas must be numbers separated by commas, got {kappas!r}") from None
    model = load_prior(prior)
    data = {name: load(name) for name in sources}
    for name, source in data.items():
        check_dimensions(source, (model.config.state_dim, model.config.action_dim), name, "the prior's training data")
    configs = [EditConfig(kappa=k, guard_disagreement=guard_disagreement) for k in candidates]  # checked before any edit
    target_model = None if target is None else fit_for_edit(load(target), guard_disagreement, seed=seed)
    results = {name: diagnose_edit(model, source, configs[0], candidates, transitions, target_model, seed=seed)
               for name, source in data.items()}
    if as_json:
        print(json.dumps({"prior": prior, "sources": results}))
        return
    for name, result in results.items():
        first = result["kappas"][0]
        print(f"{name} ({result['transitions']} steps sampled): {first['outside_support_share']:.0%} of windows beyond "
              f"the prior's support; one-step mismatch {first['source_error']:.3f} ({first['source_score']:.3f} inside "
              f"it) against the target model's resolution {first['resolution']:.3f}"
              + ("" if first["disagreement"] is None else f"; its ensemble's disagreement {first['disagreement']:.3f}"))
        for row in result["kappas"]:
            print(f"  kappa {row['kappa']:.2f}: score {row['score']:.3f}, {row['edited_share']:.0%} of windows edited")
        chosen = "none (keep the source)" if result["kappa"] is None else f"{result['kappa']:g}"
        print(f"  kappa: {chosen}: {result['reason']}")
        print(f"  {result['verdict']}")


@app.command("proxy")
def proxy(
    datasets: List[str] = typer.Argument(..., help="Datasets to measure (paths or shipped names)."),
    target: str = typer.Option(..., "--target", help="Target data the proxy is fitted to."),
    steps: int = typer.Option(ProxyConfig.steps, "--steps", min=1, help="Proxy training steps."),
    seed: int = typer.Option(0, "--seed", min=0),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """The paper's measure, no simulator needed: fit an MLP dynamics model to the target data and
    report |model(s, a) - s'| for each dataset."""
    from xted.analysis import fit_proxy
    from xted.data import load

    measured = {name: load(name) for name in datasets}
    fitted = fit_proxy(load(target), ProxyConfig(steps=steps, seed=seed), progress=not as_json)
    results = [{"path": name, **fitted.error(data).summary()} for name, data in measured.items()]
    if as_json:
        print(json.dumps({"target": target, "steps": steps, "seed": seed, "datasets": results}))
        return
    print(f"learned dynamics proxy fitted to {target} ({steps} steps, seed {seed})")
    print(f"{'dataset':40s} {'n':>7s} {'MAE':>9s} {'MSE':>9s} {'MAE p50':>9s} {'MAE p90':>9s}")
    for row in results:
        q = row["mae_quantiles"]
        print(f"{row['path'][-40:]:40s} {row['n']:7d} {row['mae']:9.4f} {row['mse']:9.4f} {q['p50']:9.4f} {q['p90']:9.4f}")


@app.command("content")
def content(
    source: str = typer.Argument(..., help="The source dataset."),
    edited: str = typer.Argument(..., help="Its edit (same episodes)."),
    env: Optional[str] = typer.Option(None, "--env", help=f"{KNOWN_ENVS}: adds the forward-velocity "
                                      "correlation."),
    velocity_index: Optional[int] = typer.Option(None, "--velocity-index", min=0,
                                                 help="The observation column of forward velocity, for data of another "
                                                 "env: adds the forward-velocity correlation."),
    cutoff: float = typer.Option(0.2, "--cutoff", min=0.01, max=1.0,
                                 help="Low-frequency band, as a fraction of the Nyquist frequency."),
    target: Optional[str] = typer.Option(None, "--target", help="The target data: adds where the edit took the "
                                         "source's mean forward velocity and return rate against the target's."),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """How much task content an edit kept: low-frequency spectrum difference and forward-velocity
    correlation per episode, against mismatched episode pairs as the chance level; with --target, the
    shift of its mean forward velocity and return rate against the target data's."""
    from xted.analysis import content_shift, content_similarity
    from xted.analysis.content import shift_text
    from xted.data import load
    from xted.envs.make import forward_velocity_index

    forward = forward_velocity_index(parse_domain(env)) if env and velocity_index is None else velocity_index
    source_data, edited_data = load(source), load(edited)
    scores = content_similarity(source_data, edited_data, forward, cutoff)
    shift = None if target is None else content_shift(source_data, edited_data, load(target), forward)
    if as_json:
        print(json.dumps({"source": source, "edited": edited, "cutoff": cutoff, **scores,
                          **({"shift": shift} if shift is not None else {})}))
        return
    for pairing, values in scores.items():
        print(f"{pairing:10s} " + "  ".join(f"{name} {value:.3f}" for name, value in values.items()))
    if shift is not None:
        print(f"shift      {shift_text(shift)}")
