"""The learned proxies' training settings. Plain Python: the CLI takes its defaults from here
without loading JAX."""

from __future__ import annotations

from dataclasses import dataclass

from xted.errors import InputError


@dataclass(frozen=True)
class ProxyConfig:
    hidden: tuple[int, ...] = (256, 256, 256)
    steps: int = 20_000
    batch_size: int = 256
    lr: float = 1e-3
    seed: int = 0

    def __post_init__(self) -> None:
        if self.steps < 1 or self.batch_size < 1 or self.lr <= 0 or not self.hidden:
            raise InputError(f"ProxyConfig: steps, batch_size, lr and hidden must be positive, got {self}")
