"""Pack a :class:`~hertzchain.model.System` into the padded work arrays of the compiled kernels."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import System
from .kernels import LAW_ELASTOPLASTIC

#: Slot counts are rounded up to a multiple of this, so that the vector loops (8 doubles with
#: AVX-512) run without a scalar remainder; it lifts a 30-bead chain from ~4.9e8 to ~6.7e8
#: bead-steps/s (measured with benchmarks/kernel.py).
PAD = 8


@dataclass
class Packed:
    """Padded arrays (see :mod:`hertzchain.integrate.kernels` for the layout)."""

    mass: np.ndarray
    inv_mass: np.ndarray
    kappa: np.ndarray
    damping: np.ndarray
    d0: np.ndarray
    de: np.ndarray
    dx0: np.ndarray
    rsum: np.ndarray
    fext: np.ndarray
    dcap: np.ndarray  # upper bound of each contact's overlap over the run [m] (System.max_overlap)
    dyield: np.ndarray  # yield overlap of each contact [m] (System.yield_overlap; elastic-plastic law)
    dmax: np.ndarray    # elastic-plastic state: largest overlap reached [m] (starts at 0)
    dres: np.ndarray    # elastic-plastic state: residual overlap of the unloading curve [m] (starts at 0)
    kres: np.ndarray    # elastic-plastic state: stiffness of the unloading curve [N/m^1.5] (starts at kappa)
    u: np.ndarray
    v: np.ndarray
    n_slots: int
    wall_slot: int


def _pad(x: np.ndarray, n: int) -> np.ndarray:
    out = np.zeros(n)
    out[: x.size] = x
    return out


def pack(system: System) -> Packed:
    """Padded copies of the system arrays; the wall ghost and padding get mass 0 and 1/m = 0.

    The elastic-plastic state starts as a contact that never yielded: dmax = dres = 0,
    kres = kappa (the yield overlaps are computed for that law only; zeros otherwise, unused).
    """
    nb = system.n_beads + 1  # moving bodies 0..N
    p = -(-(nb + 1) // PAD) * PAD  # slots: moving bodies + wall ghost, rounded up
    mass = _pad(system.mass[:nb], p)
    inv_mass = _pad(system.inv_mass[:nb], p)
    kappa = _pad(system.kappa, p)
    plastic = system.law == LAW_ELASTOPLASTIC
    return Packed(mass=mass, inv_mass=inv_mass, kappa=kappa, damping=_pad(system.damping, p),
                  d0=_pad(system.d0, p), de=_pad(system.de, p), dx0=_pad(system.dx0, p), rsum=_pad(system.rsum, p),
                  fext=_pad(system.fext[:nb], p), dcap=_pad(system.max_overlap(), p),
                  dyield=_pad(system.yield_overlap(), p) if plastic else np.zeros(p), dmax=np.zeros(p),
                  dres=np.zeros(p), kres=kappa.copy(), u=_pad(system.u0[:nb], p + 1), v=_pad(system.v0[:nb], p + 1),
                  n_slots=p, wall_slot=system.n_beads)
