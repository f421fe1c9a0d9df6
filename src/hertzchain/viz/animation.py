"""Animations of a result: the chain drawn to scale, beads coloured by force, the wall force growing beside it.

The frames are rendered with Matplotlib's Agg canvas and written as a GIF by Pillow (which
Matplotlib already needs, so nothing extra to install) or, when ``ffmpeg`` is on the PATH, as an
MP4. Beads sit at their places at rest, or displaced when the run recorded positions
(``[probes] positions = true``), with the displacement exaggerated by a stated factor (they are
micrometres against centimetre beads).
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np
import xarray as xr

from ..errors import ConfigError
from .common import bead_centres, contact_positions, result_title, select_member, time_window

if TYPE_CHECKING:  # Matplotlib loads when a figure is drawn
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

__all__ = ["ChainFrames", "chain_frames", "animate"]


@dataclass
class ChainFrames:
    """What each frame of :func:`animate` shows (SI units).

    Attributes
    ----------
    time : numpy.ndarray
        (F,) time of each frame [s] (a recorded sample).
    index : numpy.ndarray
        (F,) sample index of each frame.
    centre : numpy.ndarray
        (F, N + 1) drawn centre of the striker (column 0) and beads 1..N along the chain [m]:
        place at rest plus ``exaggeration`` times the displacement.
    force : numpy.ndarray
        (F, N + 1) colour of each body [N]: the striker's contact force F_0 and, for bead n,
        (F_{n-1} + F_n) / 2, what a sensor embedded in it would read.
    diameter : numpy.ndarray
        (N + 1,) striker and bead diameters [m].
    offset : numpy.ndarray
        (N + 1,) perpendicular offsets [m] (0 for the striker).
    exaggeration : float
        Factor applied to the displacements (0: beads drawn at rest, no positions recorded).
    wall_x : float or None
        Wall position [m], None for a free end.
    """

    time: np.ndarray
    index: np.ndarray
    centre: np.ndarray
    force: np.ndarray
    diameter: np.ndarray
    offset: np.ndarray
    exaggeration: float
    wall_x: float | None


def _nice(x: float) -> float:
    """1, 2 or 5 times a power of ten, at most ``x`` (a readable exaggeration factor)."""
    if x <= 1:
        return 1.0
    p = 10 ** math.floor(math.log10(x))
    return max(m * p for m in (1, 2, 5) if m * p <= x)


def chain_frames(ds: xr.Dataset, n_frames: int = 100, *, window: Sequence[float] | None = None,
                 member: int | None = None, exaggeration: float | None = None) -> ChainFrames:
    """The data of an animation: frame times, drawn bead centres and bead forces.

    Parameters
    ----------
    ds : xarray.Dataset
        A result with every contact force stored (batches: give ``member``).
    n_frames : int
        Number of frames, spread evenly over the record (or ``window``).
    window : (float, float) or None
        Time range [s].
    member : int or None
        Member of a batch.
    exaggeration : float or None
        Factor on the displacements; default: the 1-2-5 value that makes the largest bead
        displacement (the striker's left out: it rebounds millimetres away) at most a quarter of
        the smallest bead. Ignored (0) when the result holds no displacements.

    Returns
    -------
    ChainFrames
        The frames' data.
    """
    run = select_member(ds, member)
    if not (isinstance(n_frames, (int, np.integer)) and 2 <= n_frames <= 2000):
        raise ConfigError("--frames", f"must be an integer in 2..2000, got {n_frames!r}")
    if ("contact_force" not in run or "diameter" not in run
            or run.sizes.get("contact", 0) != run.sizes.get("contact_all", -1)):
        raise ConfigError("RESULT", "an animation needs every contact force: run with [probes] contacts = \"all\" "
                          "(the default)")
    if run.sizes.get("bead", 0) == 0:
        raise ConfigError("RESULT", "an animation draws the chain, and this run has none (chain.uniform.n = 0, the "
                          "striker onto the wall): plot its wall force instead (hertzchain plot)")
    t = run.time.values
    sel = np.flatnonzero(time_window(window, t))
    index = sel[np.round(np.linspace(0, sel.size - 1, min(n_frames, sel.size))).astype(int)]
    if index.size < n_frames:
        raise ConfigError("--frames", f"the time range holds only {sel.size} samples, fewer than {n_frames} frames")
    raw = run["model"].values.item() if "model" in run.data_vars else run.attrs.get("model", "{}")
    try:
        striker_d = float(json.loads(raw)["striker"]["diameter_mm"]) * 1e-3
    except (KeyError, TypeError, ValueError):  # a result written elsewhere: draw the paper's 8 mm striker
        striker_d = 8e-3
    phi = run.diameter.values
    n = phi.size
    f = run.contact_force.values[index]  # (F, contacts), contacts 0..N (or N-1 without a wall)
    has_wall = f.shape[1] == n + 1
    right = f[:, 1:] if has_wall else np.concatenate([f[:, 1:], np.zeros((f.shape[0], 1))], axis=1)
    force = np.concatenate([f[:, :1], 0.5 * (f[:, :n] + right)], axis=1)
    rest = np.concatenate([[-0.5 * striker_d], bead_centres(run)])
    if "displacement" in run:
        u = run.displacement.values[index]
        if exaggeration is None:
            # Scaled to the beads' own motion (micrometres), not the striker's: after its rebound the
            # striker travels millimetres, and a factor sized to that left the beads visibly still.
            # The striker, exaggerated alike, flies out of the picture (the view follows the beads).
            biggest = float(np.max(np.abs(u[:, 1:])))
            exaggeration = _nice(0.25 * float(phi.min()) / biggest) if biggest > 0 else 1.0
        if not (math.isfinite(exaggeration) and exaggeration > 0):
            raise ConfigError("--exaggeration", f"must be a positive factor, got {exaggeration!r}")
        centre = rest + exaggeration * u
    else:
        if exaggeration is not None:
            raise ConfigError("--exaggeration", "the result holds no positions: run with "
                              "--set probes.positions=true to draw the beads displaced")
        exaggeration = 0.0
        centre = np.broadcast_to(rest, force.shape).copy()
    return ChainFrames(time=t[index], index=index, centre=centre, force=force,
                       diameter=np.concatenate([[striker_d], phi]),
                       offset=np.concatenate([[0.0], run.offset.values]), exaggeration=float(exaggeration),
                       wall_x=float(contact_positions(run)[n]) if has_wall else None)


#: Frame size [in] and resolution [dpi]: 800 x 450 pixels (even, as MP4's yuv420p needs).
FRAME_INCHES, FRAME_DPI = (8.0, 4.5), 100


@dataclass
class _FrameFigure:
    """The figure of an animation: ``show(k)`` sets it to frame ``k`` (the caller draws it)."""

    figure: Figure            # with the Agg canvas attached
    chain_axes: Axes          # the chain, to scale (equal aspect), on the left
    trace_axes: Axes          # the wall force against time [ms], on the right
    trace: Line2D             # the wall force up to the frame's time
    show: Callable[[int], None]


def _frame_figure(run: xr.Dataset, fr: ChainFrames, title: str) -> _FrameFigure:
    """Lay out the frames (FRAME_INCHES at FRAME_DPI) of ``run``: the chain to scale on the
    left, its colour scale below it, the wall force growing beside it on the right."""
    import matplotlib
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.patches import Circle

    from .style import agg_figure

    fig = agg_figure(*FRAME_INCHES, layout=None, dpi=FRAME_DPI)
    # Side by side (figure fractions): a chain is ~10-20 times longer than it is wide, so drawn
    # to scale it is a thin strip; the left 55 % of the frame keeps it as long as possible and
    # leaves the trace a panel of its own height on the right.
    ax_chain = fig.add_axes((0.05, 0.42, 0.55, 0.38))
    ax_wall = fig.add_axes((0.72, 0.14, 0.26, 0.68))
    cax = fig.add_axes((0.12, 0.24, 0.41, 0.035))
    norm = Normalize(0.0, max(float(fr.force.max()), 1e-30))
    r = 0.5 * fr.diameter
    colours = ScalarMappable(norm=norm, cmap=matplotlib.colormaps["magma_r"])
    circles = [Circle((x, e), rad, edgecolor="0.3", linewidth=0.5) for x, e, rad in zip(fr.centre[0], fr.offset, r)]
    for circle in circles:
        ax_chain.add_patch(circle)
    # The view follows the beads and the striker's place at impact; an exaggerated rebound
    # carries the striker out of it to the left, as it leaves the chain.
    left = float(min(fr.centre[0, 0] - r[0], (fr.centre[:, 1:] - r[1:]).min()) - r[0])
    right = float(fr.wall_x if fr.wall_x is not None else fr.centre[:, -1].max() + r[-1])
    if fr.wall_x is not None:
        ax_chain.axvline(fr.wall_x, color="0.2", lw=3)
    ax_chain.set_xlim(left - 0.02 * (right - left), right + 0.02 * (right - left))
    ax_chain.set_ylim(-1.2 * r.max(), 1.2 * r.max())
    ax_chain.set_aspect("equal", anchor="S")  # to scale: the box shrinks to the chain's height, down to its scale
    ax_chain.set_yticks([])
    ax_chain.set_xlabel("position along the chain [m]")
    cb = fig.colorbar(colours, cax=cax, orientation="horizontal")
    cb.set_label("force on each bead [N]")
    shown = ("beads at rest (no positions recorded)" if fr.exaggeration == 0 else
             f"displacements x {fr.exaggeration:g}")
    fig.suptitle(f"{title}; colour: force on each bead; {shown}", fontsize=9)
    clock = ax_chain.set_title("", loc="left", fontsize=9)

    wall = run.wall_force.values if "wall_force" in run else None
    t_ms = run.time.values * 1e3
    span = slice(int(fr.index[0]), int(fr.index[-1]) + 1)
    ax_wall.set_xlim(t_ms[span][0], t_ms[span][-1])
    if wall is not None:
        top = float(wall[span].max())
        ax_wall.set_ylim(-0.05 * max(top, 1e-30), 1.1 * max(top, 1e-30))
        ax_wall.set_ylabel("wall force [N]")
    else:
        ax_wall.set_ylabel("(free end: no wall force)")
    (trace,) = ax_wall.plot([], [], lw=1.0, color="C3")
    ax_wall.set_xlabel("t [ms]")
    ax_wall.grid(alpha=0.3)

    def show(k: int) -> None:
        for circle, x, e, rgba_k in zip(circles, fr.centre[k], fr.offset, colours.to_rgba(fr.force[k])):
            circle.center = (x, e)
            circle.set_facecolor(rgba_k)
        clock.set_text(f"t = {fr.time[k] * 1e3:.3f} ms")
        if wall is not None:  # the trace up to the frame's sample
            trace.set_data(t_ms[span.start: fr.index[k] + 1], wall[span.start: fr.index[k] + 1])

    return _FrameFigure(fig, ax_chain, ax_wall, trace, show)


def animate(ds: xr.Dataset, out: str | Path, *, n_frames: int = 100, fps: float = 20.0,
            window: Sequence[float] | None = None, member: int | None = None,
            exaggeration: float | None = None, progress: Callable[[int, int], None] | None = None) -> Path:
    """Write an animation of a result: the chain to scale, coloured by force, and the wall force.

    Parameters
    ----------
    ds : xarray.Dataset
        A result with every contact force (see :func:`chain_frames`).
    out : str or pathlib.Path
        ``.gif`` (Pillow) or ``.mp4`` (needs ``ffmpeg`` on the PATH); written atomically.
    n_frames : int
        Number of frames.
    fps : float
        Frames per second of the file.
    window, member, exaggeration
        See :func:`chain_frames`.
    progress : callable or None
        Called as ``progress(done, total)`` after each frame.

    Returns
    -------
    pathlib.Path
        ``out``. Every frame is FRAME_INCHES x FRAME_DPI = 800 x 450 pixels.
    """
    from ..fileio import atomic_path

    out = Path(out)
    kind = out.suffix.lower()
    if kind not in (".gif", ".mp4"):
        raise ConfigError("--out", f"cannot write an animation as {out.suffix or 'a file without suffix'!r}; "
                          "use .gif or .mp4")
    ffmpeg = shutil.which("ffmpeg") if kind == ".mp4" else None
    if kind == ".mp4" and ffmpeg is None:
        raise ConfigError("--out", "an MP4 needs ffmpeg on the PATH, which was not found; write a .gif instead")
    if not (math.isfinite(fps) and 0 < fps <= 100):
        raise ConfigError("--fps", f"must lie in (0, 100], got {fps!r}")
    fr = chain_frames(ds, n_frames, window=window, member=member, exaggeration=exaggeration)
    run = select_member(ds, member)
    view = _frame_figure(run, fr, result_title(run, member if "member" in ds.dims else None))
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = view.figure.canvas
    assert isinstance(canvas, FigureCanvasAgg)  # (attached by _frame_figure)

    frames: list = []
    width, height = canvas.get_width_height()
    proc = None
    with atomic_path(out) as tmp:
        if ffmpeg is not None:
            proc = subprocess.Popen([ffmpeg, "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgba",
                                     "-s", f"{width}x{height}", "-r", f"{fps:g}", "-i", "-", "-pix_fmt", "yuv420p",
                                     "-f", "mp4", str(tmp)], stdin=subprocess.PIPE)
        for k in range(fr.time.size):
            view.show(k)
            canvas.draw()
            rgba = np.asarray(canvas.buffer_rgba())
            if proc is not None:
                assert proc.stdin is not None  # (opened with stdin=PIPE)
                proc.stdin.write(rgba.tobytes())
            else:
                from PIL import Image

                frames.append(Image.fromarray(rgba[..., :3].copy()))
            if progress is not None:
                progress(k + 1, fr.time.size)
        if proc is not None:
            assert proc.stdin is not None  # (opened with stdin=PIPE)
            proc.stdin.close()
            if proc.wait() != 0:
                raise ConfigError("--out", f"ffmpeg failed to write {out}")
        else:
            frames[0].save(tmp, format="GIF", save_all=True, append_images=frames[1:],
                           duration=round(1000 / fps), loop=0)
    return out
