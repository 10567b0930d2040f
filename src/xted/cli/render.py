"""``xted render``: an episode of a dataset as a video, alone or beside its edit."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from xted.cli.main import app
from xted.envs.domains import KNOWN_ENVS
from xted.viz.config import VideoConfig


@app.command()
def render(
    data: str = typer.Argument(..., help="Dataset (path or shipped name)."),
    env: str = typer.Option(..., "--env", help=f"{KNOWN_ENVS}."),
    gap: Optional[str] = typer.Option(None, "--gap", help="Domain whose model draws the body (default: target)."),
    episode: int = typer.Option(0, "--episode", help="Episode index (negative counts from the end)."),
    out: Path = typer.Option(..., "--out", help="Video file, .mp4 or .gif (replaced if it exists)."),
    compare: Optional[str] = typer.Option(None, "--compare",
                                          help="Edited dataset (same episodes): drawn beside DATA, same episode."),
    steps: Optional[int] = typer.Option(None, "--steps", min=1, help="Only the first N steps (default: all)."),
    width: int = typer.Option(VideoConfig.width, "--width", help="Width of one panel in pixels (multiple of 16)."),
    height: int = typer.Option(VideoConfig.height, "--height", help="Height in pixels (multiple of 16)."),
    fps: Optional[float] = typer.Option(VideoConfig.fps, "--fps", help="Frames per second (default: real time)."),
) -> None:
    """Render an episode headless (MuJoCo offscreen: EGL, else OSMesa; MUJOCO_GL picks one).

    Observations hold every state but the root's x position, which is integrated from the forward
    velocity, so the body travels through the scene. With --compare, DATA and the edited dataset are
    drawn side by side, each frame labelled with its step. A rendered edited episode shows the
    states as the editor wrote them, drawn one by one: not a simulator rollout of its actions, so it
    can show poses or motion the physics would not produce. Both are drawn with the model of
    --env/--gap. GIFs suit short clips (--steps); every frame is kept until the file is written."""
    from xted.data import load
    from xted.envs import parse_domain
    from xted.viz.render import render_episode
    from xted.viz.video import check_video_path

    check_video_path(out)
    config = VideoConfig(width=width, height=height, fps=fps)
    domain = parse_domain(env, gap)
    source = load(data)
    edited = None if compare is None else load(compare)
    labels = ("source", "edited") if compare is not None else (Path(data).stem, "")
    result = render_episode(domain, source, out, episode, edited, labels, steps, config)
    typer.echo(f"{result['out']}: episode {episode}, {result['frames']} frames of {domain.name} "
               f"in {result['seconds']:.1f} s")
