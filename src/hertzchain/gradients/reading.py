"""What an objective gives the derivative engines (:class:`Reading`), and the pieces the objective
modules share: the refusals of objectives that are zero or undefined over the run, the vertex of
a parabola through three steps."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from ..errors import ObjectiveUndefined

if TYPE_CHECKING:
    import numpy as np

__all__ = ["Reading", "STEP", "span", "rising", "never", "vertex"]

#: The complex step of the objectives' own partials.
STEP = 1e-30


@dataclass
class Reading:
    """An objective's value and partials.

    Attributes
    ----------
    value : float
        The objective [its unit].
    samples : list of (int, int, float)
        (sample, contact, dJ/dF) partials on recorded forces.
    steps : list of (int, int, float)
        (step, contact, dJ/dF) partials on the forces of single steps.
    direct : dict
        ``{System array name: dJ/d array}`` where the objective reads a System array itself.
    arrays : tuple of three arrays, optional
        More (step, contact, dJ/dF) partials as arrays (an objective that reads every step).
    final_dres : numpy.ndarray, optional
        dJ/d(each contact's residual overlap at the end of the run) (the plastic work).
    """

    value: float
    samples: list = field(default_factory=list)
    steps: list = field(default_factory=list)
    direct: dict = field(default_factory=dict)
    arrays: tuple | None = None
    final_dres: np.ndarray | None = None


def span(tape, window=None) -> str:
    """The run's time span in words (ms), for the refusals."""
    text = f"0 to {tape.time[-1] * 1e3:.4g} ms"
    return text if window is None else f"window {window[0] * 1e3:g} to {window[1] * 1e3:g} ms of a run of {text}"


def rising(tape, name: str) -> ObjectiveUndefined:
    """The refusal of a maximum found at the run's last step: the force is still rising when the run
    ends (the pulse is arriving), so the maximum is no peak, and its time is the run's end."""
    return ObjectiveUndefined("run.duration", f"the force {name} reads is still rising when the run ends "
                              f"({span(tape)}): its peak lies beyond the run; lengthen run.duration (or leave it "
                              "'auto')")


def never(tape, name: str, why: str | None = None) -> ObjectiveUndefined:
    """The refusal of an objective that stays zero over the run: the pulse never reaches the
    protected body (or ``why``, naming what to change)."""
    if why is not None:
        return ObjectiveUndefined("objective", f"{name} is 0 and so is every derivative: {why}")
    return ObjectiveUndefined("run.duration", f"the pulse does not reach the protected body within the run "
                              f"({span(tape)}): {name} is 0 and so is every derivative; lengthen run.duration (or "
                              "leave it 'auto')")


def vertex(fb, fpk, fa, h0, h1, t_pk):
    """Vertex (value, time) of the parabola through three steps (``verlet.refine_peak``), complex-safe."""
    s01 = (fpk - fb) / h0
    s12 = (fa - fpk) / h1
    c = (s12 - s01) / (h0 + h1)
    b = s12 - c * h1
    return fpk - 0.25 * b * b / c, t_pk - 0.5 * b / c
