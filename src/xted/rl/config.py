"""The RL configurations: one validating dataclass per algorithm (each field with its help text;
the fields are ``--set FIELD=VALUE`` overrides) and the online run's settings. Plain Python: the
CLI takes its defaults and help from here without loading JAX."""

from __future__ import annotations

import dataclasses
import json

from xted.fields import check_fields, setting
from xted.errors import InputError

ONLINE_ALGORITHM_NAMES = ("sac", "td3")  # xted.rl.online.ONLINE_ALGORITHMS
OFFLINE_STEPS = 30_000  # gradient updates of an offline run: xted.train_policy, xted policy and the bench
TRAINING_SEGMENT = 1000  # offline updates per jitted call: losses are recorded and the bar moves once a segment


@dataclasses.dataclass(frozen=True)
class IQLConfig:
    hidden: tuple[int, ...] = setting((256, 256), "Hidden layer widths of the actor, both critics and the value net.")
    actor_lr: float = setting(3e-4, "Actor (AWR) learning rate.")
    critic_lr: float = setting(3e-4, "Q-network learning rate.")
    value_lr: float = setting(3e-4, "Value-network learning rate.")
    discount: float = setting(0.99, "Discount factor gamma.")
    tau: float = setting(0.005, "Polyak rate of the target Q-networks.")
    expectile: float = setting(0.7, "Expectile tau of the value loss (IQL Eq. 5); 0.5 is a mean.")
    temperature: float = setting(3.0, "Inverse temperature beta of advantage-weighted regression (IQL Eq. 7).")
    max_weight: float = setting(100.0, "Upper clip on the AWR weight exp(beta * advantage).")
    batch_size: int = setting(256, "Transitions per gradient step.")
    normalize_rewards: bool = setting(False, "Scale rewards by 1000 / (max - min episode return), as IQL does for "
                                             "locomotion.")

    def __post_init__(self) -> None:
        check_fields(self)


@dataclasses.dataclass(frozen=True)
class SACConfig:
    hidden: tuple[int, ...] = setting((256, 256), "Hidden layer widths of the actor and both critics.")
    learning_rate: float = setting(3e-4, "Learning rate of actor, critics and temperature.")
    discount: float = setting(0.99, "Discount factor gamma.")
    tau: float = setting(0.005, "Polyak rate of the target critics.")
    batch_size: int = setting(256, "Transitions per gradient step.")
    init_temperature: float = setting(1.0, "Initial entropy temperature alpha (tuned toward -|A| entropy).")

    def __post_init__(self) -> None:
        check_fields(self)


@dataclasses.dataclass(frozen=True)
class TD3BCConfig:
    hidden: tuple[int, ...] = setting((256, 256), "Hidden layer widths of the actor and both critics.")
    actor_lr: float = setting(1e-5, "Actor learning rate (offline default: the xTED paper's; TD3's and "
                                         "TD3+BC's own, online TD3's default: 3e-4).")
    critic_lr: float = setting(1e-3, "Critic learning rate (offline default: the xTED paper's; TD3's and "
                                          "TD3+BC's own, online TD3's default: 3e-4).")
    discount: float = setting(0.99, "Discount factor gamma.")
    tau: float = setting(0.005, "Polyak rate of the target networks.")
    alpha: float = setting(2.5, "Weight alpha of the Q term against behaviour cloning (TD3+BC Eq. 5); 0 is BC.")
    policy_noise: float = setting(0.2, "Std of the target-policy smoothing noise.")
    noise_clip: float = setting(0.5, "Clip of that noise.")
    policy_delay: int = setting(2, "Critic updates per actor (and target) update.")
    batch_size: int = setting(256, "Transitions per gradient step.")
    behaviour_cloning: bool = setting(True, "Add the BC term (TD3+BC); false is TD3 itself.")

    def __post_init__(self) -> None:
        check_fields(self)


@dataclasses.dataclass(frozen=True)
class BCConfig:
    hidden: tuple[int, ...] = setting((256, 256), "Hidden layer widths of the policy.")
    learning_rate: float = setting(3e-4, "Learning rate.")
    batch_size: int = setting(256, "Transitions per gradient step.")

    def __post_init__(self) -> None:
        check_fields(self)


@dataclasses.dataclass(frozen=True)
class DARAConfig:
    eta: float = setting(0.1, "Weight eta of the reward correction r + eta * clip(delta) (DARA's reward augmentation).")
    clip: float = setting(10.0, "Clip on the correction delta, in log-probability units.")
    classifier_steps: int = setting(5000, "Training steps of the two domain classifiers.")
    classifier_hidden: tuple[int, ...] = setting((256, 256), "Hidden layer widths of each classifier.")
    classifier_lr: float = setting(3e-4, "Classifier learning rate.")
    classifier_batch: int = setting(256, "Transitions per classifier step (half target, half source).")
    input_noise: float = setting(0.1, "Std of the Gaussian noise on classifier inputs (a regulariser, as in DARC).")
    iql: IQLConfig = setting(IQLConfig(), "The IQL backbone trained on the corrected rewards (iql.FIELD=VALUE).")

    def __post_init__(self) -> None:
        check_fields(self)


@dataclasses.dataclass(frozen=True)
class IGDFConfig:
    keep_fraction: float = setting(0.5, "Share xi of each batch's source transitions kept, those of highest score "
                                        "(the authors' README: 0.25 for halfcheetah, 0.75 for walker2d).")
    weight_scale: float = setting(1.0, "alpha: a kept source transition's Q loss is weighted exp(alpha * score).")
    encoder_hidden: tuple[int, ...] = setting((256, 256), "Hidden layer widths of both encoders.")
    embedding_dim: int = setting(64, "Width of the embeddings phi(s, a) and psi(s').")
    encoder_steps: int = setting(7000, "Adam steps of the contrastive encoders.")
    encoder_lr: float = setting(3e-4, "Encoder learning rate.")
    encoder_batch: int = setting(128, "Target transitions per encoder step; as many source next states are negatives.")
    iql: IQLConfig = setting(IQLConfig(), "The IQL backbone trained on the filtered data (iql.FIELD=VALUE).")

    def __post_init__(self) -> None:
        check_fields(self)


@dataclasses.dataclass(frozen=True)
class OTDFConfig:
    keep_fraction: float = setting(0.8, "Share of each batch's source transitions kept, those of least deviation.")
    epsilon: float = setting(0.05, "Entropic regularisation of the transport, relative to the mean scaled cost.")
    sinkhorn_iterations: int = setting(100, "Most Sinkhorn iterations per source chunk.")
    sinkhorn_tolerance: float = setting(1e-9, "Sinkhorn stops once the marginals err less than this.")
    chunk: int = setting(4096, "Source transitions per transport problem (memory: chunk x target transitions).")
    vae_hidden: tuple[int, ...] = setting((750, 750), "Hidden layer widths of the behaviour CVAE's encoder and "
                                                      "decoder.")
    vae_steps: int = setting(10_000, "Adam steps of the behaviour CVAE on the target's actions.")
    vae_lr: float = setting(1e-3, "CVAE learning rate.")
    vae_batch: int = setting(128, "Target transitions per CVAE step.")
    kl_weight: float = setting(0.5, "Weight of the CVAE's KL term against its reconstruction MSE.")
    behaviour_weight: float = setting(0.5, "The actor loss subtracts this x mean log beta(pi(s) | s).")
    behaviour_samples: int = setting(10, "Latent samples of the log-sum-exp estimate of log beta.")
    behaviour_redraw_every: int = setting(1000, "Updates between draws of each state's decoded behaviour actions (a "
                                                "multiple of 1,000); every update reads its states' current draw.")
    behaviour_variance: float = setting(0.1, "Variance of the Gaussian N(a; dec(s, z), variance I) around each "
                                             "decoded action.")
    iql: IQLConfig = setting(IQLConfig(), "The IQL backbone trained on the filtered data (iql.FIELD=VALUE).")

    def __post_init__(self) -> None:
        check_fields(self)
        if self.behaviour_redraw_every < 1 or self.behaviour_redraw_every % TRAINING_SEGMENT:
            raise InputError(f"OTDFConfig.behaviour_redraw_every must be a positive multiple of {TRAINING_SEGMENT:,}, "
                             f"got {self.behaviour_redraw_every}")


# The offline learners by their CLI names (``xted policy --algo``), with their configs.
OFFLINE_ALGORITHMS: dict[str, type] = {"iql": IQLConfig, "td3bc": TD3BCConfig, "bc": BCConfig, "dara": DARAConfig,
                                       "igdf": IGDFConfig, "otdf": OTDFConfig}
# Learners that wrap an IQL backbone (their ``iql`` field) and change what it trains on.
IQL_WRAPPERS = (DARAConfig, IGDFConfig, OTDFConfig)


@dataclasses.dataclass(frozen=True)
class OnlineRunConfig:
    # TD3 is the behaviour-policy algorithm BENCHMARKS.md chose (same return per step as SAC, cheaper).
    algo: str = setting("td3", " or ".join(ONLINE_ALGORITHM_NAMES) + ".")
    total_steps: int = setting(1_000_000, "Total environment steps (one update each).")
    start_steps: int = setting(5_000, "Uniform-random steps before learning.")
    checkpoint_every: int = setting(10_000, "Steps between checkpoints with a greedy evaluation.")
    eval_episodes: int = setting(10, "Episodes per greedy evaluation.")
    block: int = setting(50, "Environment steps (then as many updates) per jitted call.")
    exploration_noise: float = setting(0.1, "Std of TD3's Gaussian action noise.")
    seed: int = setting(0, "Seed of networks, exploration and environments.")
    stop_at_return: float | None = setting(None, "End the run at the first greedy evaluation whose mean return "
                                                 "reaches this.")
    stop_above_pitch: float | None = setting(
        None, "End the run at the first greedy evaluation whose mean |root pitch| (radians) exceeds this: drop a "
        "cheetah that has flipped onto its back (about 3; upright runs stay under 0.5), a local optimum that "
        "further training does not leave.")
    terminate_above_pitch: float | None = setting(
        None, "While training, end an episode (as a terminal, as a fall ends a walker's) when |root pitch| exceeds "
        "this many radians and add upright_bonus to the reward of every step before (Walker2d's healthy reward), "
        "so a halfcheetah learns to run upright; evaluations and datasets use the plain domain and its rewards.")
    upright_bonus: float = setting(1.0, "Reward per upright training step with terminate_above_pitch.")
    init_from: str | None = setting(None, "A finished run of the same algo whose networks this run starts from "
                                          "(fine-tune a policy trained in another domain).")
    sac: SACConfig = setting(SACConfig(), "SAC's settings (sac.FIELD=VALUE).")
    # Online TD3 keeps TD3's own learning rates: the offline defaults are tuned for 20k fixed transitions.
    td3: TD3BCConfig = setting(TD3BCConfig(actor_lr=3e-4, critic_lr=3e-4, behaviour_cloning=False),
                               "TD3's settings (td3.FIELD=VALUE).")

    def __post_init__(self):
        if self.algo not in ONLINE_ALGORITHM_NAMES:
            raise InputError(f"unknown online algorithm {self.algo!r}; known: {', '.join(ONLINE_ALGORITHM_NAMES)}")
        for name in ("total_steps", "checkpoint_every", "eval_episodes", "block"):
            if getattr(self, name) <= 0:
                raise InputError(f"{name} must be positive, got {getattr(self, name)}")
        if self.start_steps < 0 or self.exploration_noise < 0 or self.upright_bonus < 0 or self.seed < 0:
            raise InputError("start_steps, exploration_noise, upright_bonus and seed must be >= 0")
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
