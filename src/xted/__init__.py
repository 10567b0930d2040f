"""xted: cross-domain trajectory editing with diffusion models."""

__version__ = "0.1.0"
