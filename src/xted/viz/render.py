"""Render an episode of a dataset to a video, alone or side by side with its edit.

What is drawn is the recorded states, one frame per step, in the given domain's model. An edited
episode is drawn as the editor wrote its states: no simulator rolls its actions out, so a body
that floats or slides shows states the target physics would not produce.
"""

from __future__ import annotations

import time
from pathlib import Path

import mujoco
from tqdm.auto import tqdm

from xted.analysis.content import check_same_episodes
from xted.data import Dataset
from xted.envs import Domain, simulator
from xted.errors import InputError
from xted.viz.config import VideoConfig
from xted.viz.episode import episode_observations, episode_states, set_state
from xted.viz.labels import draw_label, side_by_side
from xted.viz.offscreen import OffscreenRenderer
from xted.viz.video import check_video_path, write_video


def render_episode(domain: Domain, data: Dataset, out: str | Path, episode: int = 0, compare: Dataset | None = None,
                   labels: tuple[str, str] = ("source", "edited"), steps: int | None = None,
                   config: VideoConfig = VideoConfig(), progress: bool = True) -> dict:
    """Write episode ``episode`` of ``data`` (with ``compare``: beside the same episode of it) to
    ``out`` (``.mp4`` or ``.gif``), each frame labelled with its step. Returns what was written."""
    out = check_video_path(out)
    if steps is not None and steps < 1:
        raise InputError(f"steps must be positive, got {steps}")
    episodes = [episode_observations(data, episode)]
    if compare is not None:
        check_same_episodes(data, compare)
        episodes.append(episode_observations(compare, episode))
    model, frame_skip = simulator(domain)
    dt = model.opt.timestep * frame_skip
    states = [episode_states(model, observations[:steps], dt) for observations in episodes]
    length = len(states[0][0])
    started = time.perf_counter()
    with OffscreenRenderer(model, config.width, config.height, config.camera_distance) as renderer:
        datas = [mujoco.MjData(model) for _ in states]

        def frames():
            for t in tqdm(range(length), desc=f"render {out.name}", unit="frame", disable=not progress):
                panels = []
                for label, (qpos, qvel), state in zip(labels, states, datas):
                    set_state(model, state, qpos[t], qvel[t])
                    panels.append(draw_label(renderer.render(state), f"{label}  step {t}"))
                yield side_by_side(panels)

        written = write_video(frames(), out, config.fps or 1.0 / dt)
    return {"out": str(out), "domain": domain.name, "episode": episode, "frames": written,
            "panels": len(states), "seconds": time.perf_counter() - started}
