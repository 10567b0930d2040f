"""The learned proxies' training settings. Plain Python: the CLI takes its defaults from here
without loading JAX."""

from __future__ import annotations

from dataclasses import dataclass

from xted.errors import InputError
from xted.fields import setting


@dataclass(frozen=True)
class ProxyConfig:
    hidden: tuple[int, ...] = setting((256, 256, 256), "Hidden layer widths of the MLP.")
    steps: int = setting(20_000, "Adam steps.")
    batch_size: int = setting(256, "Transitions per step.")
    learning_rate: float = setting(1e-3, "Peak learning rate (cosine-decayed to 0 over the steps).")
    seed: int = setting(0, "Seed of initialisation and batches.")


    def __post_init__(self) -> None:
        if self.steps < 1 or self.batch_size < 1 or self.learning_rate <= 0 or not self.hidden:
            raise InputError(f"ProxyConfig: steps, batch_size, learning_rate and hidden must be positive, got {self}")
