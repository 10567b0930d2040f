"""xted's public Python API, as the CLI runs it: load data, train or load a prior, edit, measure.

    import xted
    target = xted.load_dataset("halfcheetah-medium-replay")     # a path, a shipped name or minari:ID
    source = xted.load_dataset("halfcheetah-thigh")
    prior = xted.train_prior(target, out="runs/prior")          # resumable, with a progress bar
    prior = xted.load_prior("halfcheetah-medium-replay-cpu")    # a shipped prior's name, or a folder
    edited = prior.edit(source, kappa=0.5, seed=0)              # a Dataset with the source's schema
    report = xted.measure_edit(source, edited, target=target, env="halfcheetah")
    policy = xted.train_policy("iql", target, sources=[edited], steps=30_000, env="halfcheetah")
    policy.save("runs/policy")                                  # env=None: trains without a simulator
    policy = xted.load_policy("runs/policy")
    action = policy.act(observation)

Every name is exported from ``xted`` itself and loaded on first use, so ``import xted`` stays light.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

from xted.data import Dataset
from xted.errors import InputError
from xted.rl.config import OFFLINE_STEPS

if TYPE_CHECKING:
    from xted.envs.step_function import StepFunction


def load_dataset(source: str | Path) -> Dataset:
    """A dataset from a ``.npz`` / D4RL-style ``.hdf5`` file, a local Minari dataset (``minari:ID``
    or its folder), or a dataset shipped with xted by name (``xted data list``)."""
    from xted.data import load

    return load(source)


def save_dataset(dataset: Dataset, path: str | Path) -> Path:
    """Write ``dataset`` to ``path`` (atomically), its format chosen by the path: ``.npz``, D4RL-style
    ``.hdf5`` / ``.h5``, or a folder without a suffix for a Minari dataset; returns the path."""
    from xted.data import save

    return save(dataset, path).path


def train_prior(target: Dataset | str | Path, out: str | Path, preset: str = "cpu", steps: int = 20_000,
                seed: int = 0, heldout_episodes: int = 0, progress: bool = True, **fields: Any):
    """Train (or resume, in ``out``) a diffusion prior on ``target`` and return it, loaded.

    ``preset``: ``cpu`` (small, fast) or ``paper``; ``fields`` replace any of its
    :class:`~xted.diffusion.config.PriorConfig` fields (``decay_steps=20_000``, ...);
    ``heldout_episodes`` random target episodes are left out of training (to measure the floor): they
    are ``xted.split_heldout(target, heldout_episodes)[1]``."""
    from xted.data import split_heldout
    from xted.fields import known_fields
    from xted.diffusion.config import PriorConfig
    from xted.diffusion.config import preset as make_preset
    from xted.diffusion.prior import load_prior
    from xted.diffusion.training import train_prior_folder

    data = load_dataset(target) if isinstance(target, (str, Path)) else target
    data, _ = split_heldout(data, heldout_episodes)
    config = make_preset(preset, data.observation_dim, data.action_dim, rewards=data.has_rewards, seed=seed,
                         **known_fields(PriorConfig, fields))
    return load_prior(train_prior_folder(data, out, config, steps, progress=progress))


def measure_edit(source: Dataset, edited: Dataset, target: Dataset | None = None,
                 env: str | StepFunction | None = None,
                 proxy_steps: int = 20_000, seed: int = 0, velocity_index: int | None = None) -> dict:
    """What an edit did: ``content`` always (how much of the source's task content it kept);
    ``proxy`` with ``target`` (the paper's measure: one-step error of source and edit under an MLP
    dynamics model fitted to the target, ``proxy_steps`` Adam steps); ``simulator`` with ``env``:
    an env xted simulates (``halfcheetah``, ``walker2d``, ``hopper``, ``ant`` or their Gymnasium ids; every
    transition replayed in that target simulator), or your own step function
    ``f(observations [N, d], actions [N, a]) -> next observations [N, d]`` (one-step errors only: it
    gives no rewards). ``velocity_index``: the observation column of forward velocity, for the
    content measure's correlation (xted knows it for the envs it simulates). With ``target``, ``shift`` too:
    the mean forward velocity and return rate of source, edit and target, and whether the edit's is nearer
    the target's."""
    from xted.analysis import ProxyConfig, edit_report, fit_proxy
    from xted.envs import parse_domain

    proxy = None if target is None else fit_proxy(target, ProxyConfig(steps=proxy_steps, seed=seed), progress=False)
    dynamics = parse_domain(env) if isinstance(env, str) else env
    return edit_report(dynamics, source, edited, proxy, velocity_index, target)



def train_policy(algo: str, target: Dataset | str | Path, sources: Sequence[Dataset | str | Path] = (),
                 steps: int = OFFLINE_STEPS, seed: int = 0, env: str | None = None, gap: str | None = None,
                 eval_every: int = 10_000, eval_episodes: int = 10, progress: bool = True, **fields: Any):
    """Train an offline policy (``iql``, ``td3bc``, ``bc``, ``dara``, ``igdf`` or ``otdf``) on ``target`` + ``sources``
    and return it (a :class:`~xted.rl.policy_io.Policy`: ``act``, ``save``, ``scores``).

    ``env`` (``halfcheetah``, ``walker2d``, ``hopper`` or ``ant``, with ``gap`` for another domain of it) evaluates the
    policy every ``eval_every`` steps in that simulator; None trains without one (data of any
    robot). ``fields`` replace fields of the algorithm's config (``expectile=0.9``,
    ``hidden=(64, 64)``; DARA's backbone as ``iql=IQLConfig(...)``)."""
    import dataclasses

    from xted.fields import known_fields
    from xted.envs import parse_domain
    from xted.rl.offline_train import default_config, train_offline

    config = default_config(algo)
    config = dataclasses.replace(config, **known_fields(type(config), fields))
    if gap is not None and env is None:
        raise InputError("gap names a domain of an env: give env too")
    domain = None if env is None else parse_domain(env, gap)
    data = [load_dataset(d) if isinstance(d, (str, Path)) else d for d in (target, *sources)]
    (result,) = train_offline(config, data[0], data[1:], domain, steps, [seed], eval_every=eval_every,
                              eval_episodes=eval_episodes, progress=progress)
    return result["policy"]


def load_policy(source: str | Path):
    """A policy saved by ``Policy.save``, or by ``xted policy --save DIR`` (DIR itself when it holds
    one seed's policy, else ``DIR/seed_N``)."""
    from xted.rl.policy_io import POLICY_FILE, Policy

    path = Path(source)
    if path.is_dir() and not (path / POLICY_FILE).exists():
        seeds = sorted(p.parent.name for p in path.glob(f"seed_*/{POLICY_FILE}"))
        if len(seeds) == 1:
            path = path / seeds[0]
        elif seeds:
            raise InputError(f"{path} holds the policies of {len(seeds)} seeds ({', '.join(seeds)}): "
                             f"load one of them, e.g. {path / seeds[0]}")
    return Policy.load(path)
