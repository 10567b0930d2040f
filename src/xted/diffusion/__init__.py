"""The diffusion prior, one concept per module: ``schedule`` (noise schedule and samplers),
``denoiser`` (the networks), ``config`` (PriorConfig and presets), ``objective`` (loss and train
step), ``checkpoint`` (a training folder on disk), ``training`` (the train loop), ``prior`` (the
trained artefact) and ``editor`` (trajectory editing, which needs only the artefact and the
denoiser). Names are importable from the package too, loaded on first use, so that importing the
editor does not load the training stack.
"""

import importlib

_EXPORTS = {
    "CROSS_WIRING": "denoiser", "Denoiser": "denoiser", "DenoiserConfig": "denoiser",
    "EditConfig": "editor", "edit_dataset": "editor", "edit_windows": "editor",
    "Schedule": "schedule", "cosine_schedule": "schedule", "ddim_step": "schedule", "ddim_timesteps": "schedule",
    "ddpm_step": "schedule", "q_sample": "schedule",
    "PriorConfig": "config", "preset": "config", "presets": "config",
    "TrainState": "objective", "loss_fn": "objective", "make_train_step": "objective", "train_step": "objective",
    "Prior": "prior", "load_prior": "prior", "export_prior": "prior",
    "train_prior": "training",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module 'xted.diffusion' has no attribute {name!r}")
    return getattr(importlib.import_module(f"xted.diffusion.{_EXPORTS[name]}"), name)
