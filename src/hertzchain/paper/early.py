"""Start drawing the laws figure of a reproduction before the analysis stack is imported.

``hertzchain reproduce --from-data`` is CPU-bound on two cores, and its process spends its first
second importing Matplotlib, SciPy, xarray and the analysis while the other core idles. The
model-variant laws figure (``fig5_laws``, :func:`hertzchain.paper.law_figure.fig_laws`) needs
only ``summary.json``, Matplotlib and :mod:`hertzchain.theory`, so :func:`start_laws_figure`,
which imports nothing heavy itself, forks a process that imports those (~0.5 s) and draws it on
that idle core (measured on two cores: benchmarks/README.md, ``ux_timings.py``).
"""

from __future__ import annotations

import json
import multiprocessing
from pathlib import Path
from typing import Callable

from ..interrupts import forked_pool
from ..parallel import usable_cores
from .values import PAPER

__all__ = ["start_laws_figure"]


def _draw_laws(out_dir: str, laws: dict, eps: float) -> Path:
    # Matplotlib and hertzchain.theory only: the figure is done before the parent's imports are
    from .law_figure import fig_laws
    from ..viz.style import save_figure

    return save_figure(fig_laws(laws, eps), Path(out_dir), "fig5_laws")


def start_laws_figure(out_dir: str | Path) -> Callable[..., dict[str, Path]] | None:
    """Draw ``fig5_laws`` of the reproduction in ``out_dir`` in a process forked now.

    Parameters
    ----------
    out_dir : str or pathlib.Path
        A reproduction's folder (its ``summary.json`` holds the numbers drawn).

    Returns
    -------
    callable or None
        ``finish(cancel=False)``: waits for the figure and returns ``{"fig5_laws": png path}``;
        ``cancel=True`` stops the process instead (after a failure elsewhere). None when nothing
        was started: ``summary.json`` unreadable or without model-variant numbers (the caller
        reports or skips it), one usable core, or no ``fork`` on this platform (the caller
        draws the figure itself).
    """
    from ..received import read_received
    from .inputs import check_laws

    try:  # a regular file of the folder only (hertzchain.received: a FIFO would hang the read)
        summary = json.loads(read_received(Path(out_dir) / "summary.json", out_dir).decode("utf-8"))
        laws = summary["fidelity"]["laws"]
        eps = summary["settings"].get("eps_target") or PAPER["eps"]
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None
    if check_laws(laws) is not None or not (isinstance(eps, (int, float)) and 0 < eps <= 1):
        return None  # damaged: the redraw names what is wrong
    cores = usable_cores()
    if not laws or cores < 2 or "fork" not in multiprocessing.get_all_start_methods():
        return None
    pool = forked_pool(1)
    pending = pool.apply_async(_draw_laws, (str(out_dir), laws, eps))

    def finish(cancel: bool = False) -> dict[str, Path]:
        if cancel:
            pool.terminate()
            pool.join()
            return {}
        path = pending.get()
        pool.close()
        pool.join()
        return {"fig5_laws": path}

    return finish
