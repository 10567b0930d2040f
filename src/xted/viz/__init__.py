"""Pictures and videos: episodes rendered headless with MuJoCo, and plots of xted's measures and
runs. Names are loaded on first use (``xted.viz.config`` stays light)."""

from xted.lazy import lazy_exports

_EXPORTS = {"VideoConfig": "config", "render_episode": "render"}

__all__ = sorted(_EXPORTS)
__getattr__ = lazy_exports(__name__, _EXPORTS)
