"""The typed structures the compiled runs take, instead of dozens of positional arrays.

Numba compiles a NamedTuple as one typed argument (its fields' types make the signature, and the
on-disk cache keys on them); a run unpacks its structures at the top, so its loops read the same
local arrays as before and compile to the same code. The arrays are those of
:func:`hertzchain.integrate.core.layout.pack` (``P`` slots, layout of
:mod:`hertzchain.integrate.core.kernels`).

- :class:`ChainArrays`: the chain as every run reads it (the fourth-order runs of
  :mod:`hertzchain.integrate.drivers.rkn_kernels` too);
- the Verlet family (``kernels._verlet_run``, the loop :mod:`.generated` builds from a registry
  law, the threaded runs of :mod:`hertzchain.integrate.drivers.threaded`): :class:`VerletState`,
  :class:`ContactArrays`, :class:`Extension`, :class:`VerletProbes` and :class:`VerletControl`.
  The fourth-order runs keep their own state, probes and step control (other fields: no plastic
  work, protected body or block schedule; an error tolerance instead).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["ChainArrays", "ContactArrays", "Extension", "VerletState", "VerletProbes", "VerletControl"]


class ChainArrays(NamedTuple):
    """The chain as the runs read it: padded per-slot arrays (``layout.pack``) and the wall's slot."""

    mass: np.ndarray       # [kg]
    inv_mass: np.ndarray   # [1/kg]
    kappa: np.ndarray      # Hertz constants [N/m^1.5] (a registry law's stiffness k)
    damping: np.ndarray    # the law's damping (A [s] or gamma [kg/s]; a registry law's parameter p)
    d0: np.ndarray         # static overlaps [m]
    fext: np.ndarray       # external forces [N]
    wall_slot: int         # contact N (the wall's), also where the peak is tracked


class ContactArrays(NamedTuple):
    """Per-contact arrays of the Verlet runs besides :class:`ChainArrays`': the offset pairs'
    geometry (zeros for aligned pairs), each contact's overlap bound over the run (the adaptive
    step's estimate) and the per-contact state, carried in place from chunk to chunk: the
    elastic-plastic law's (``kernels.elastoplastic_force``) or, in ``dmax``, a registry law's."""

    de: np.ndarray      # perpendicular offset difference e_{j+1} - e_j [m]
    dx0: np.ndarray     # axial distance of centres at rest [m]
    rsum: np.ndarray    # R_j + R_{j+1} [m]
    dcap: np.ndarray    # upper bound of the overlap over the run [m] (System.max_overlap)
    dyield: np.ndarray  # yield overlap [m] (elastic-plastic law)
    dmax: np.ndarray    # largest overlap reached [m] (elastic-plastic law), a registry law's state
    dres: np.ndarray    # residual overlap of the unloading curve [m] (elastic-plastic law)
    kres: np.ndarray    # stiffness of the unloading curve [N/m^1.5] (elastic-plastic law)


class Extension(NamedTuple):
    """A protected body and mass-in-mass beads (``kernels.step_extended``): the extension array
    ``ext`` (P, EXT_COLUMNS), (0, EXT_COLUMNS) without; ``on`` whether the model has one;
    ``body_slot`` the protected body's slot (N + 1), else -1."""

    ext: np.ndarray
    on: bool
    body_slot: int


class VerletState(NamedTuple):
    """What a run carries from chunk to chunk: positions ``u`` [m] and synchronised velocities
    ``v`` [m/s] (P + 1 slots), accelerations ``a`` [m/s^2] (P), forces ``g`` [N] (P + 1, shifted by
    one) at a sample time, and ``acc`` (8 slots): [dissipated energy (J), last dissipated power
    (W), step count, current steps per block, relax count, largest steps per block allowed in
    the relax window, largest and smallest steps per block used]."""

    u: np.ndarray
    v: np.ndarray
    a: np.ndarray
    g: np.ndarray
    acc: np.ndarray


class VerletProbes(NamedTuple):
    """What a run records at sample k: the forces [N] of the contacts ``rec`` in row k of
    ``out_f``, the kinetic, potential and dissipated energies [J] in ``out_ke``, ``out_pe``,
    ``out_ed``, the elastic-plastic law's plastic work [J] in ``out_wp``, the velocities [m/s] and
    (threaded runs; a single-thread run's driver copies ``u`` between its calls) positions [m] of
    bodies 0..N when ``record_v`` / ``record_u``, every contact's largest sampled force in ``fmax``
    [N], the protected body's [displacement, velocity, acceleration, work] in row k of ``out_b``;
    ``peak`` (8 slots) tracks the wall force between steps (``kernels._verlet_run``)."""

    rec: np.ndarray
    out_f: np.ndarray
    out_ke: np.ndarray
    out_pe: np.ndarray
    out_ed: np.ndarray
    out_wp: np.ndarray
    out_v: np.ndarray
    record_v: bool
    out_u: np.ndarray
    record_u: bool
    fmax: np.ndarray
    peak: np.ndarray
    out_b: np.ndarray


class VerletControl(NamedTuple):
    """Samples ``interval`` [s] apart, each cut into ``n_sub`` blocks of ``stride`` steps (fixed
    step), or (``stride`` == 0, adaptive) of steps chosen every ``n_eval`` blocks for omega dt <=
    1 / ``c_steps``, allowed to grow after ``relax`` evaluations in a row
    (``drivers.verlet.StepPlan``)."""

    interval: float
    stride: int
    n_sub: int
    n_eval: int
    c_steps: float
    relax: int
