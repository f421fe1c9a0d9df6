"""Pack a :class:`~hertzchain.model.System` into the padded work arrays of the compiled kernels."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...model import System
from .extension import EXT_CLIN, EXT_COLUMNS, EXT_IMIN, EXT_KIN, EXT_KLIN, EXT_MIN
from .kernels import LAW_ELASTOPLASTIC
from .structures import ChainArrays, ContactArrays, Extension

#: Slot counts are rounded up to a multiple of this, so that the vector loops (8 doubles with
#: AVX-512) run without a scalar remainder; it lifts a 30-bead chain from ~4.9e8 to ~6.7e8
#: bead-steps/s (measured with benchmarks/kernel.py).
PAD = 8


@dataclass
class Packed:
    """Padded arrays (see :mod:`hertzchain.integrate.core.kernels` for the layout)."""

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
    ext: np.ndarray          # (P, EXT_COLUMNS) extension (kernels.EXT_*), (0, EXT_COLUMNS) when not extended
    body_slot: int           # N + 1 with a protected body, else -1

    def chain(self) -> ChainArrays:
        """The chain's arrays as the compiled runs take them (views, not copies)."""
        return ChainArrays(self.mass, self.inv_mass, self.kappa, self.damping, self.d0, self.fext, self.wall_slot)

    def contacts(self) -> ContactArrays:
        """The contacts' geometry, overlap bounds and state as the Verlet runs take them (views)."""
        return ContactArrays(self.de, self.dx0, self.rsum, self.dcap, self.dyield, self.dmax, self.dres, self.kres)

    def extension(self) -> Extension:
        """The extension as the Verlet runs take it (on when ``ext`` has rows: an extended system)."""
        return Extension(self.ext, self.ext.shape[0] > 0, self.body_slot)


def _pad(x: np.ndarray, n: int) -> np.ndarray:
    out = np.zeros(n)
    out[: x.size] = x
    return out


def extension(system: System, p: int) -> np.ndarray:
    """The kernels' extension array (``kernels.EXT_*`` columns) of an extended system, P slots: the
    mount of a protected body as the linear contact N + 1 (to the immovable ghost N + 2), the
    internal masses and springs of mass-in-mass bodies, internal state at rest (0)."""
    ext = np.zeros((p, EXT_COLUMNS))
    n = system.n_beads
    if system.body:
        ext[n + 1, EXT_KLIN] = system.mount_k
        ext[n + 1, EXT_CLIN] = system.mount_c
    if system.res_k is not None:
        assert system.res_m is not None  # set together with res_k (bodies.extend)
        nb = system.n_moving
        inner = system.res_m[:nb] > 0
        ext[:nb, EXT_KIN] = system.res_k[:nb]
        ext[:nb, EXT_MIN] = system.res_m[:nb]
        ext[:nb, EXT_IMIN] = np.where(inner, 1.0 / np.where(inner, system.res_m[:nb], 1.0), 0.0)
    return ext


def pack(system: System) -> Packed:
    """Padded copies of the system arrays; the wall ghost and padding get mass 0 and 1/m = 0.

    The elastic-plastic state starts as a contact that never yielded: dmax = dres = 0,
    kres = kappa (the yield overlaps are computed for that law only; zeros otherwise, unused).
    A protected body is slot N + 1 and its mount contact N + 1 (its deflection at rest in d0).
    """
    nb = system.n_moving  # moving bodies 0..N (and the protected body N + 1)
    p = -(-(nb + 1) // PAD) * PAD  # slots: moving bodies + wall (or ground) ghost, rounded up
    mass = _pad(system.mass[:nb], p)
    inv_mass = _pad(system.inv_mass[:nb], p)
    kappa = _pad(system.kappa, p)
    plastic = system.law == LAW_ELASTOPLASTIC
    d0 = _pad(system.d0, p)
    if system.body:
        d0[system.n_beads + 1] = system.mount_d0  # the mount's deflection at rest (contact N + 1)
    ext = extension(system, p) if system.extended else np.zeros((0, EXT_COLUMNS))
    return Packed(mass=mass, inv_mass=inv_mass, kappa=kappa, damping=_pad(system.damping, p),
                  d0=d0, de=_pad(system.de, p), dx0=_pad(system.dx0, p), rsum=_pad(system.rsum, p),
                  fext=_pad(system.fext[:nb], p), dcap=_pad(system.max_overlap(), p),
                  dyield=_pad(system.yield_overlap(), p) if plastic else np.zeros(p), dmax=np.zeros(p),
                  dres=np.zeros(p), kres=kappa.copy(), u=_pad(system.u0[:nb], p + 1), v=_pad(system.v0[:nb], p + 1),
                  n_slots=p, wall_slot=system.n_beads, ext=ext, body_slot=system.n_beads + 1 if system.body else -1)
