"""The Agg figure factory and the look of the paper's figures (Matplotlib only).

:func:`agg_figure` makes every figure of the package: a :class:`~matplotlib.figure.Figure` on its
own Agg canvas, so the global pyplot state and the session's backend are never touched.
:data:`STYLE` is the paper's two-column format (~3.4 in a column, ~7 in a full width, 8-pt
fonts), with its colours, :func:`paper_figure`, :func:`styled`, :func:`panel_tag` and
:func:`save_figure` (PNG + PDF, written atomically), used by :mod:`hertzchain.paper.figures`.
Nothing here imports the analysis stack (SciPy, xarray), so that a process can draw with it
early: :mod:`hertzchain.paper.early`.
"""

from __future__ import annotations

from functools import wraps
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Literal

import matplotlib
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

if TYPE_CHECKING:
    from matplotlib.typing import RcKeyType

__all__ = ["STYLE", "agg_figure", "paper_figure", "styled", "panel_tag", "save_figure"]

#: Matplotlib style for the paper's column widths (8-pt fonts, thin lines).
STYLE: dict[RcKeyType, Any] = {
    "font.size": 8, "axes.labelsize": 8, "axes.titlesize": 8, "legend.fontsize": 7,
    "xtick.labelsize": 7, "ytick.labelsize": 7, "lines.linewidth": 1.0, "lines.markersize": 3.5,
    "axes.linewidth": 0.6, "xtick.major.width": 0.6, "ytick.major.width": 0.6,
    "xtick.direction": "in", "ytick.direction": "in", "xtick.top": True, "ytick.right": True,
    "legend.frameon": False, "legend.handlelength": 1.8, "legend.borderaxespad": 0.3,
    "mathtext.default": "regular", "savefig.dpi": 200,
    # Type 3 fonts in the PDFs: embedding TrueType (type 42) subsets each font with fontTools,
    # ~0.3 s per font and figure, most of the time --from-data took.
    "pdf.fonttype": 3,
}

C1, C2, C3, CK = "#1f77b4", "#d62728", "#2ca02c", "0.2"


def agg_figure(width: float, height: float, *,
               layout: Literal["constrained", "compressed", "tight"] | None = "constrained", dpi: float | None = None) -> Figure:
    """A figure of ``width`` x ``height`` inches on its own Agg canvas (no pyplot state).

    Parameters
    ----------
    width, height : float
        Size [in].
    layout : str or None
        Matplotlib layout engine (``"constrained"``; None: positions set by hand).
    dpi : float or None
        Resolution [dots per inch] (None: Matplotlib's default).

    Returns
    -------
    matplotlib.figure.Figure
        The empty figure, its canvas attached.
    """
    fig = Figure(figsize=(width, height), layout=layout, dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def paper_figure(width: float, height: float) -> Figure:
    """An :func:`agg_figure` with the paper's tight padding between panels."""
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    fig = agg_figure(width, height)
    engine = fig.get_layout_engine()
    assert isinstance(engine, ConstrainedLayoutEngine)  # agg_figure's default layout
    engine.set(w_pad=0.03, h_pad=0.03, wspace=0.04, hspace=0.04)
    return fig


def styled(func: Callable) -> Callable:
    """Draw under :data:`STYLE` (font sizes are fixed when artists are created)."""

    @wraps(func)
    def wrapper(*args, **kwargs):
        with matplotlib.rc_context(STYLE):
            return func(*args, **kwargs)

    return wrapper


def panel_tag(ax, text: str, loc: str = "upper left") -> None:
    """Panel letter, e.g. "(b)", inside the axes."""
    x, ha = (0.03, "left") if "left" in loc else (0.97, "right")
    y, va = (0.95, "top") if "upper" in loc else (0.05, "bottom")
    ax.text(x, y, text, transform=ax.transAxes, ha=ha, va=va, fontweight="bold")


def save_figure(fig: Figure, out_dir: str | Path, name: str, dpi: int = 200) -> Path:
    """Write ``name.png`` (raster, ``dpi`` dots per inch) and ``name.pdf`` (vector) into ``out_dir``.

    The directory is created if needed; both files are written atomically. The layout is
    computed for the PNG and kept for the PDF; the figure is left without a layout engine.
    Returns the PNG path (the PDF lies beside it, same stem).
    """
    from ..fileio import atomic_path

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    png = out / f"{name}.png"
    with matplotlib.rc_context(STYLE):
        if not isinstance(fig.canvas, FigureCanvasAgg):
            FigureCanvasAgg(fig)
        # written through hertzchain.fileio: a killed or failed save never leaves half a figure
        with atomic_path(png) as tmp:
            fig.savefig(tmp, dpi=dpi, format="png")
        # The PDF keeps the PNG's layout. No layout engine at all, not "none": that leaves a
        # placeholder engine, and with any engine savefig first runs a whole dry-run draw (text
        # layout and mathtext on a renderer of its own) before the real one: 40 % of the PDF's
        # time, 0.8 s CPU over the reproduction's eight figures, for byte-identical files (but
        # for the PDF's date). None means "no engine" only while the rc parameters ask for no
        # automatic layout, hence the context.
        with matplotlib.rc_context({"figure.autolayout": False, "figure.constrained_layout.use": False}):
            fig.set_layout_engine(None)
        with atomic_path(png.with_suffix(".pdf")) as tmp:
            fig.savefig(tmp, format="pdf")
    return png
