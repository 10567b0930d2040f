"""The RL configurations: one validating dataclass per algorithm (its fields are ``--set
FIELD=VALUE`` overrides) and the online run's settings. Plain Python: the CLI takes its defaults
from here without loading JAX."""

from __future__ import annotations

import dataclasses
import json

from xted.config import check_fields
from xted.errors import InputError

ONLINE_ALGORITHM_NAMES = ("sac", "td3")  # xted.rl.online.ONLINE_ALGORITHMS


@dataclasses.dataclass(frozen=True)
class IQLConfig:
    hidden: tuple[int, ...] = (256, 256)
    actor_lr: float = 3e-4
    critic_lr: float = 3e-4
    value_lr: float = 3e-4
    discount: float = 0.99
    tau: float = 0.005
    expectile: float = 0.7
    temperature: float = 3.0
    max_weight: float = 100.0
    batch_size: int = 256
    normalize_rewards: bool = False

    def __post_init__(self) -> None:
        check_fields(self)


@dataclasses.dataclass(frozen=True)
class SACConfig:
    hidden: tuple[int, ...] = (256, 256)
    learning_rate: float = 3e-4
    discount: float = 0.99
    tau: float = 0.005
    batch_size: int = 256
    init_temperature: float = 1.0

    def __post_init__(self) -> None:
        check_fields(self)


@dataclasses.dataclass(frozen=True)
class TD3BCConfig:
    hidden: tuple[int, ...] = (256, 256)
    actor_lr: float = 3e-4
    critic_lr: float = 3e-4
    discount: float = 0.99
    tau: float = 0.005
    alpha: float = 2.5
    policy_noise: float = 0.2
    noise_clip: float = 0.5
    policy_delay: int = 2
    batch_size: int = 256
    behaviour_cloning: bool = True

    def __post_init__(self) -> None:
        check_fields(self)


@dataclasses.dataclass(frozen=True)
class BCConfig:
    hidden: tuple[int, ...] = (256, 256)
    lr: float = 3e-4
    batch_size: int = 256

    def __post_init__(self) -> None:
        check_fields(self)


@dataclasses.dataclass(frozen=True)
class DARAConfig:
    eta: float = 0.1
    clip: float = 10.0
    classifier_steps: int = 5000
    classifier_hidden: tuple[int, ...] = (256, 256)
    classifier_lr: float = 3e-4
    classifier_batch: int = 256
    input_noise: float = 0.1
    iql: IQLConfig = IQLConfig()

    def __post_init__(self) -> None:
        check_fields(self)


@dataclasses.dataclass(frozen=True)
class OnlineRunConfig:
    algo: str = "td3"  # the behaviour-policy algorithm BENCHMARKS.md chose (same return per step as SAC, cheaper)
    total_steps: int = 1_000_000
    start_steps: int = 5_000  # uniform-random actions before learning starts
    checkpoint_every: int = 10_000
    eval_episodes: int = 10
    block: int = 50  # environment steps (then as many updates) per jitted call
    exploration_noise: float = 0.1  # TD3's Gaussian action noise
    seed: int = 0
    stop_at_return: float | None = None  # end the run at the first greedy evaluation that reaches this
    # End the run at the first evaluation whose mean |root pitch| (radians) exceeds this: a cheetah
    # on its back (about 3) is a local optimum that further training does not leave.
    stop_above_pitch: float | None = None
    # Training only: end an episode (a terminal, as a fall ends a walker's) once |root pitch| exceeds
    # this, and add upright_bonus to every step's reward before it (Walker2d's healthy reward), so that
    # ending early never pays and the policy learns to stay upright. Evaluations and the data made
    # later run the plain domain with its own rewards.
    terminate_above_pitch: float | None = None
    upright_bonus: float = 1.0
    init_from: str | None = None  # a finished run of the same algo whose networks this run starts from
    sac: SACConfig = SACConfig()
    td3: TD3BCConfig = TD3BCConfig(behaviour_cloning=False)

    def __post_init__(self):
        if self.algo not in ONLINE_ALGORITHM_NAMES:
            raise InputError(f"unknown online algorithm {self.algo!r}; known: {', '.join(ONLINE_ALGORITHM_NAMES)}")
        for name in ("total_steps", "checkpoint_every", "eval_episodes", "block"):
            if getattr(self, name) <= 0:
                raise InputError(f"{name} must be positive, got {getattr(self, name)}")
        if self.start_steps < 0 or self.exploration_noise < 0 or self.upright_bonus < 0:
            raise InputError("start_steps, exploration_noise and upright_bonus must be >= 0")
        for name in ("stop_above_pitch", "terminate_above_pitch"):
            if getattr(self, name) is not None and not getattr(self, name) > 0:
                raise InputError(f"{name} must be > 0 radians, got {getattr(self, name)}")
        if self.td3.behaviour_cloning:
            raise InputError("online TD3 has no behaviour data to clone: td3.behaviour_cloning must be False")

    @property
    def agent(self) -> SACConfig | TD3BCConfig:
        return self.sac if self.algo == "sac" else self.td3

    def fingerprint(self) -> dict:
        """What makes two runs the same run: everything but how far it goes."""
        fields = json.loads(json.dumps(dataclasses.asdict(self)))
        fields.pop("total_steps")
        fields.pop("stop_at_return")
        fields.pop("stop_above_pitch")
        if self.terminate_above_pitch is None:
            fields.pop("upright_bonus")  # unused, and runs recorded before it existed stay the same runs
        fields.pop("sac" if self.algo == "td3" else "td3")
        return fields
