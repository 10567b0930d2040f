"""The diffusion prior, one concept per module: ``schedule`` (noise schedule and samplers),
``denoiser`` (the networks), ``config`` (DenoiserConfig, PriorConfig and its presets, EditConfig:
plain Python), ``objective`` (loss and train step), ``checkpoint`` (a training folder on disk),
``training`` (the train loop), ``prior`` (the trained artefact) and ``editor`` (trajectory
editing, which needs only the artefact and the denoiser). Names are importable from the package
too, loaded on first use, so that importing the editor does not load the training stack.
"""

from xted.lazy import lazy_exports

_EXPORTS = {
    "CROSS_WIRING": "config", "Denoiser": "denoiser", "DenoiserConfig": "config",
    "EditConfig": "config", "edit_dataset": "editor", "edit_windows": "editor",
    "Schedule": "schedule", "cosine_schedule": "schedule", "ddim_step": "schedule", "ddim_timesteps": "schedule",
    "ddpm_step": "schedule", "q_sample": "schedule",
    "PriorConfig": "config", "preset": "config", "presets": "config",
    "TrainState": "objective", "loss_fn": "objective", "make_train_step": "objective", "train_step": "objective",
    "Prior": "prior", "load_prior": "prior", "export_prior": "prior",
    "train_prior_folder": "training",
}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_exports(__name__, _EXPORTS)
