"""Objectives that read the state of the run, not only its recorded forces: a protected body's
peaks, the time a yielded wall contact stops being compressed, the energy delivered to the body and
the plastic work. Their partials include *state seeds* (a position or velocity after a step,
:func:`hertzchain.integrate.differentiate.state_seed`), and the primal numbers they need are
those of the taped run, run again from its checkpoints (``differentiate.replay``, ``state_after``).
"""

from __future__ import annotations

import numpy as np

from .reading import STEP, Reading, never, rising, vertex

__all__ = ["body_peak", "yielded_wall", "overlap_peak_time", "BODY"]

#: Objectives of a protected body (``[wall] type = "body"``), as the design search computes them
#: (:mod:`hertzchain.design.body`).
BODY = frozenset({"peak_body_force", "peak_body_acceleration", "energy_to_body"})


def body_peak(tape, name: str) -> Reading:
    """The largest magnitude over the samples of the protected body's force to the ground
    k x + c v (x = u_b + the mount's deflection at rest) or of its acceleration
    (F_N - F_(N+1) + f_ext) / M, and its partials: on the body's state after the sample's last step
    (state seeds) or on the two forces of that step, and on the mount's k, c, deflection and 1/M.

    The sample of the maximum is held fixed (as every maximum over samples). The force's sample is
    found from the mount's recorded force (which sees the velocity half a step earlier), then
    among its neighbours on the exact k x + c v of the state run again from a checkpoint."""
    from ..integrate import differentiate as D

    sy, w = tape.system, tape.packed
    n = sy.n_beads
    b = n + 1
    col = {int(c): i for i, c in enumerate(tape.contacts)}
    fn, fm = tape.forces[:, col[n]], tape.forces[:, col[b]]
    if name == "peak_body_acceleration":
        acc = (fn - fm + w.fext[b]) * w.inv_mass[b]
        k = int(np.argmax(np.abs(acc)))
        if not abs(acc[k]) > 0.0:
            raise never(tape, name)
        sign = 1.0 if acc[k] > 0 else -1.0
        step = tape.sample_step(k)
        inv_mass, fext = np.zeros(sy.mass.size), np.zeros(sy.mass.size)
        inv_mass[b] = sign * (fn[k] - fm[k] + w.fext[b])
        fext[b] = sign * w.inv_mass[b]
        return Reading(float(abs(acc[k])), steps=[(step, n, sign * w.inv_mass[b]), (step, b, -sign * w.inv_mass[b])],
                       direct={"inv_mass": inv_mass, "fext": fext})
    k0 = int(np.argmax(np.abs(fm)))
    if not abs(fm[k0]) > 0.0:
        raise never(tape, name)
    best = None
    for k in range(max(k0 - 2, 1), min(k0 + 3, tape.time.size)):
        u, v, _ = D.state_after(tape, k)
        x = float(sy.mount_d0) + u[b]
        f = float(sy.mount_k) * x + float(sy.mount_c) * v[b]
        if best is None or abs(f) > abs(best[1]):
            best = (k, f, x, v[b])
    k, f, x, vb = best
    if k == tape.time.size - 1:
        raise rising(tape, name)
    sign = 1.0 if f > 0 else -1.0
    step = tape.sample_step(k)
    return Reading(abs(f), steps=[(step, D.state_seed(b), sign * float(sy.mount_k)),
                                  (step, D.state_seed(b, velocity=True), sign * float(sy.mount_c))],
                   direct={"mount_k": np.array([sign * x]), "mount_c": np.array([sign * vb]),
                           "mount_d0": np.array([sign * float(sy.mount_k)])})


def yielded_wall(tape, wall: int) -> bool:
    """Whether the wall contact went plastic (Thornton's law, its largest overlap past the yield
    overlap) without a viscous part: its force then peaks where its overlap stops growing, with a
    kink in the force's curvature there (loading line, steeper unloading curve)."""
    from ..integrate import kernels

    w = tape.packed
    return (tape.system.law == kernels.LAW_ELASTOPLASTIC and w.damping[wall] == 0.0
            and w.dmax[wall] > w.dyield[wall])


def overlap_peak_time(tape, wall: int) -> Reading:
    """The time the wall overlap stops growing: the vertex of the parabola through the overlap
    delta_N = u_N - u_(N+1) + d0_N at the three steps around its largest value, and its partials
    on those positions (state seeds). The overlap is smooth there (its second derivative is the
    relative acceleration, continuous), where the force's curvature jumps from Thornton's loading
    line to the stiffer unloading curve: a parabola through three forces across that kink misplaces
    the peak by a fraction of a step that cycles as the peak moves from step to step, and its
    derivative then differs from the trend by ~13 % (issue 38); the overlap's vertex does not."""
    from ..integrate import differentiate as D

    starts = np.concatenate([[0], np.cumsum(np.add.reduceat(tape.ns_log, np.arange(0, tape.ns_log.size,
                                                                                    tape.group)))])
    gi = int(np.searchsorted(starts, tape.peak_step, side="right")) - 1
    first, u, h = D.replay(tape, gi - 1, gi + 1)
    body = wall + 1
    delta = u[:, wall] - u[:, body] + tape.packed.d0[wall]
    r = int(np.argmax(delta))
    if not 0 < r < delta.size - 1:  # the largest overlap at an end of the run: no vertex
        raise rising(tape, "peak_wall_time")
    t = (max(gi - 1, 0) * tape.group) * float(tape.time[1] - tape.time[0]) / tape.plan.n_sub + np.cumsum(h)
    weights = []
    for i in range(3):
        e = [0j, 0j, 0j]
        e[i] = 1j * STEP
        _, tv = vertex(delta[r - 1] + e[0], delta[r] + e[1], delta[r + 1] + e[2], h[r], h[r + 1], t[r])
        weights.append(tv.imag / STEP)
    _, time = vertex(delta[r - 1], delta[r], delta[r + 1], h[r], h[r + 1], t[r])
    seeds = []
    for i, wgt in enumerate(weights):
        step = first + r - 1 + i
        seeds.append((step, D.state_seed(wall), wgt))
        if tape.system.body:  # a protected body moves: its position enters the overlap too
            seeds.append((step, D.state_seed(body), -wgt))
    return Reading(float(time.real), steps=seeds)
