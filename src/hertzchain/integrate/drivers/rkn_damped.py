"""Driver of ``"rkn4"`` on the dissipative laws and offset beads
(:mod:`hertzchain.integrate.drivers.rkn_damped_kernels`).

``simulate(model, integrator="rkn4")`` (and ``"auto"``, which picks it) on a chain with
Kuwabara-Kono's or the dashpot law (``viscoelastic``, ``viscoelastic_scaled``,
``viscoelastic_sized``, ``dashpot``, ``dashpot_scaled``; forces clipped at zero), or with beads
offset from the axis (any of these laws or the elastic one; the force F(delta) along the line of
centres, F dx / d of it along the axis): the classical fourth-order Runge-Kutta-Nystrom method for
y'' = f(y, y'), a step control bounding every loaded contact's local velocity error (its Hertz and
viscous singular terms at closing, its frequency and its damping rate) and landing on every
closing, clip and reload, the dissipated energy integrated with the method's weights (fourth
order), probes interpolated between steps. Accuracy: ``rtol`` (``eps`` here is
``rkn.DAMPED_EPS`` rtol times the striker speed [m/s]); at the default
:data:`hertzchain.integrate.drivers.rkn.RKN_RTOL` the peak wall force of the paper's chain 1 with its
calibrated dashpot is within ~4e-7 of DOP853 at rtol 1e-12 and KE + PE + dissipated within ~3e-8
of the striker's energy (tests/test_rkn_dissipative.py, benchmarks/time_to_accuracy.py).
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ...model import System
from . import rkn_damped_kernels as rk
from ..core.layout import pack
from .rkn_kernels import SAMPLE_BLOCK, ChainArrays, ProbeBuffers, StepControl
from .rkn_chunks import advance_in_chunks, rkn_raw_run
from .verlet import RawRun

__all__ = ["run_rkn_damped"]


def run_rkn_damped(system: System, duration: float, sample_interval: float, dt: float | None, eps: float,
                   record_velocities: bool, contacts: np.ndarray | None, progress: Callable[[int, int], None] | None,
                   chunk_steps: int, record_positions: bool) -> RawRun:
    """Integrate a dissipative or offset ``system`` for ``duration`` [s] (module docstring).

    Called by :func:`hertzchain.integrate.drivers.rkn.run_rkn`, which checked the model and the options;
    ``eps`` [m/s] is the local velocity error allowed per step, ``dt`` [s] a fixed step (no step
    control, no event location) or None. Other parameters and the result as ``run_rkn``'s.
    """
    n_samples = int(math.floor(duration / sample_interval + 1e-9)) + 1
    nc = system.n_contacts
    nb = system.n_beads + 1
    w = pack(system)
    p = w.n_slots
    law = int(system.law)
    u, v = w.u, w.v
    # accelerations, new state, stage state (one slot more, always 0, read by contact P - 1), stages
    a, an, un, vn, us, vs = (np.zeros(p + 1) for _ in range(6))
    k2, k3, k4, up, vp, ap = (np.zeros(p) for _ in range(6))
    fi = np.zeros((nc, SAMPLE_BLOCK))  # a block of samples' forces (rkn_samples)
    ed = np.zeros((2, rk.ROWS, p))
    ends = np.zeros((2, rk.ENDS))
    pw = np.zeros(p)  # per contact: stage-weighted dissipated power
    mode = np.zeros(p)  # per contact: its branch in the present step (1: carries a force)
    last = np.zeros(p)  # ... in the last step (at the start: the state's)
    # offset pairs' geometry (rows rk.G_*); an aligned chain's has no columns, so that aligned and
    # misaligned chains share one compiled run (the kernels test the width once, outside their loops)
    off = np.ascontiguousarray(np.stack([w.de, w.dx0, w.rsum])) if system.misaligned else np.zeros((3, 0))
    rk.accelerations(u, v, w.kappa, w.damping, w.d0, off, w.fext, w.inv_mass, law, a)
    rk.end_data(u, v, a, w.kappa, w.damping, w.d0, off, w.fext, w.mass, law, last, 0.0, ed, ends, 0)
    rk.set_modes(ed, 0, last)  # the state's branches (on which a is f(u, v)), and the power on them
    rk.end_data(u, v, a, w.kappa, w.damping, w.d0, off, w.fext, w.mass, law, last, 0.0, ed, ends, 0)
    rec = np.arange(nc) if contacts is None else np.asarray(contacts, dtype=np.int64)
    out_f = np.empty((n_samples, rec.size))
    out_ke = np.empty(n_samples)
    out_pe = np.empty(n_samples)
    out_d = np.empty(n_samples)
    out_v = np.empty((n_samples if record_velocities else 1, nb))
    out_u = np.empty((n_samples if record_positions else 1, nb))
    f0 = ed[0, rk.R_F, :nc].copy()
    out_f[0] = f0[rec]
    out_ke[0] = ends[0, rk.E_KE]
    out_pe[0] = ends[0, rk.E_PE]
    out_d[0] = 0.0
    out_v[0] = v[:nb]
    out_u[0] = u[:nb]
    fmax = f0.copy()
    peak = np.array([f0[system.n_beads] if system.has_wall else 0.0, 0.0])
    acc = np.array([0.0, 0.0, 0.0, 0.0, np.inf, 0.0, 0.0])

    per_call = max(1, round(chunk_steps * 1e-6 / sample_interval))
    state = rk.DampedState(u, v, a, un, vn, an, us, vs, k2, k3, k4, pw, mode, last, up, vp, ap, fi, ed, ends)
    chain = ChainArrays(w.mass, w.inv_mass, w.kappa, w.damping, w.d0, w.fext, system.n_beads)
    probes = ProbeBuffers(rec, out_f, out_ke, out_pe, out_d, out_v, bool(record_velocities), out_u,
                          bool(record_positions), fmax, peak)
    control = StepControl(float(sample_interval), 0.0 if dt is None else float(dt), float(eps), float(duration))
    advance_in_chunks(lambda k, k_stop: rk.damped_run(state, chain, off, law, probes, control, k, k_stop, acc),
                      n_samples, per_call, sample_interval, dt is not None, progress)
    return rkn_raw_run(probes, acc, sample_interval, dt is not None, out_d)
