"""``hertzchain animate``: a GIF or MP4 of a result."""

from __future__ import annotations

from pathlib import Path

import click

from .common import open_result, parse_window, progress_bar


@click.command("animate")
@click.argument("result", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "-o", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="FILE.gif (always available) or FILE.mp4 (needs ffmpeg).")
@click.option("--frames", type=int, default=100, show_default=True, help="Number of frames.")
@click.option("--fps", type=float, default=20.0, show_default=True, help="Frames per second.")
@click.option("--window", metavar="T0,T1", default=None, help="Time range to animate [ms], e.g. 1.0,2.5.")
@click.option("--member", type=int, default=None, help="Run of a batch to animate.")
@click.option("--exaggeration", type=float, default=None,
              help="Factor on the displacements (default: the largest one a quarter of the smallest bead).")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def animate(result: Path, out: Path, frames: int, fps: float, window: str | None, member: int | None,
            exaggeration: float | None, quiet: bool) -> None:
    """Animate RESULT: the chain to scale, beads coloured by force, the wall force growing beside it.

    Beads are drawn displaced when the run recorded positions (hertzchain run CONFIG --set
    probes.positions=true), at rest otherwise.
    """
    from ..fileio import check_not_input
    from ..viz.animation import animate as write_animation

    check_not_input(out, result)
    span = parse_window(window)
    ds = open_result(result)
    with progress_bar("drawing frames", enabled=not quiet) as update:
        write_animation(ds, out, n_frames=frames, fps=fps, window=span, member=member, exaggeration=exaggeration,
                        progress=update)
    click.echo(f"wrote {out} ({frames} frames)")
