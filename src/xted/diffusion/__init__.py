"""The diffusion prior: noise schedule, xTED denoiser, training and trajectory editing."""

from xted.diffusion.denoiser import CROSS_WIRING, Denoiser, DenoiserConfig
from xted.diffusion.editor import EditConfig, edit_dataset, edit_windows
from xted.diffusion.schedule import Schedule, cosine_schedule, ddim_step, ddim_timesteps, ddpm_step, q_sample
from xted.diffusion.training import (
    Prior,
    PriorConfig,
    TrainState,
    load_prior,
    loss_fn,
    make_train_step,
    preset,
    presets,
    train_prior,
    train_step,
)

__all__ = [
    "CROSS_WIRING",
    "Denoiser",
    "DenoiserConfig",
    "EditConfig",
    "Prior",
    "PriorConfig",
    "Schedule",
    "TrainState",
    "cosine_schedule",
    "ddim_step",
    "ddim_timesteps",
    "ddpm_step",
    "edit_dataset",
    "edit_windows",
    "load_prior",
    "loss_fn",
    "make_train_step",
    "preset",
    "presets",
    "q_sample",
    "train_prior",
    "train_step",
]
