"""Objectives that read the state of the run, not only its recorded forces: a protected body's
peaks, the time a yielded wall contact stops being compressed, the energy delivered to the body and
the plastic work. Their partials include *state seeds* (a position or velocity after a step,
:func:`hertzchain.integrate.derivatives.differentiate.state_seed`), and the primal numbers they need are
those of the taped run, run again from its checkpoints (``differentiate.replay``, ``state_after``).
"""

from __future__ import annotations

import numpy as np

from .reading import STEP, Reading, never, rising, vertex

__all__ = ["body_peak", "yielded_wall", "overlap_peak_time", "energy_to_body", "plastic_work",
           "residual_overlap_max", "BODY"]

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
    from ..integrate.derivatives import differentiate as D

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
    assert best is not None  # (a tape holds more than one sample: the loop ran)
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
    from ..integrate.core import kernels

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
    from ..integrate.derivatives import differentiate as D

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


def energy_to_body(tape) -> Reading:
    """The most energy the chain had delivered to the protected body at a sample: the work of
    contact N on it, W = sum over steps of h/2 (P_(s-1) + P_s), P_s = F_N^(s) vp_b^(s), the
    trapezoids the engine sums (``kernels``: the body's record), and its partials.

    The run is replayed group by group for the body's position and velocity at every step; the
    force of contact N at step s is M a_(s+1) + F_mount^(s) - f_ext, with a_(s+1) from velocity
    Verlet's kicks (:func:`_accelerations`), exact to rounding, and the recorded one at the samples'
    steps. The partials: on F_N of every step up to the sample of the maximum
    (held fixed), and on the velocity the step sees, vp_s = v_s + h_s a_s: the state after step
    s - 1 (a state seed) and the forces on the body then."""
    from ..integrate.derivatives import differentiate as D

    sy, w = tape.system, tape.packed
    n = sy.n_beads
    b = n + 1
    col = {int(c): i for i, c in enumerate(tape.contacts)}
    inv_m, fext = float(w.inv_mass[b]), float(w.fext[b])
    k_m, c_m, d0_m = float(sy.mount_k), float(sy.mount_c), float(sy.mount_d0)
    pos, vel, hs = [], [], []
    for _, u, vp, h in D.replay_groups(tape, tape.n_steps - 1):
        pos.append(u[:, b].copy())
        vel.append(vp[:, b].copy())
        hs.append(h.copy())
    ub, vp, h = np.concatenate(pos), np.concatenate(vel), np.concatenate(hs)
    fm = k_m * (ub + d0_m) + c_m * vp  # the mount's force at every step (kernels.forces_linear)
    a0 = (tape.forces[0, col[n]] - tape.forces[0, col[b]] + fext) * inv_m
    acc = _accelerations(vp, h, a0)  # a_s after step s - 1, s = 0 .. steps
    fn = acc[1:] / inv_m + fm - fext
    ends = tape.step_end[1:] - 1  # the steps of samples 1..: their recorded forces, exactly
    fn[ends] = tape.forces[1:, col[n]]
    power = fn * vp
    p_prev = np.concatenate([[tape.forces[0, col[n]] * float(sy.v0[b])], power[:-1]])
    work = np.cumsum(0.5 * h * (p_prev + power))
    series = np.concatenate([[0.0], work[ends]])
    k = int(np.argmax(series))
    if not series[k] > 0.0:
        raise never(tape, "energy_to_body")
    if k == series.size - 1:
        raise rising(tape, "energy_to_body")
    last = int(ends[k - 1])
    steps = np.arange(last + 1)
    c = 0.5 * h[:last + 1]
    c[:-1] += 0.5 * h[1:last + 1]  # each P_s enters two trapezoids (one, the last)
    a_s = acc[:last + 1]  # after step s - 1 (the initial one for s = 0)
    wv = c * fn[:last + 1]  # dW/d vp_s
    wa = wv * h[:last + 1]  # dW/d a_s: vp_s = v_s + h_s a_s
    prev = steps - 1
    arrays = (np.concatenate([steps, prev, prev, prev]),
              np.concatenate([np.full(steps.size, n), np.full(steps.size, D.state_seed(b, velocity=True)),
                              np.full(steps.size, n), np.full(steps.size, b)]),
              np.concatenate([c * vp[:last + 1], wv, wa * inv_m, -wa * inv_m]))
    d_inv_mass, d_fext = np.zeros(sy.mass.size), np.zeros(sy.mass.size)
    d_inv_mass[b] = float(np.sum(wa * a_s)) / inv_m  # a_s = net force x 1/M
    d_fext[b] = float(np.sum(wa)) * inv_m
    return Reading(float(series[k]), arrays=arrays, direct={"inv_mass": d_inv_mass, "fext": d_fext})


def _accelerations(vp: np.ndarray, h: np.ndarray, a0: float) -> np.ndarray:
    """A body's accelerations a_s after every step s - 1 (a_0 given) from the velocities its forces
    see, vp_s = v_s + h_s a_s (``tape``'s step convention): v_(s+1) = vp_s - h_s/2 a_s + h_s/2 a_(s+1),
    so a_(s+1) = (vp_(s+1) - vp_s + h_s/2 a_s) / (h_s/2 + h_(s+1)) (the last with h_(s+1) = h_s:
    its own vp is not needed, its force is recorded)."""
    out = np.empty(h.size + 1)
    out[0] = a0
    hn = np.append(h[1:], h[-1])
    vn = np.append(vp[1:], np.nan)
    a = a0
    for s in range(h.size):  # a recursion: a short loop of floats (the errors shrink by ~1/3 a step)
        a = (vn[s] - vp[s] + 0.5 * h[s] * a) / (0.5 * h[s] + hn[s])
        out[s + 1] = a
    return out


def _plastic_work(kappa, dy, dm, dres):
    """Each contact's plastic work [J] (``integrate.energies.plastic_work``, vectorised, complex-safe)."""
    sy = np.sqrt(dy)
    fy = kappa * dy * sy
    x = dm - dy
    fmax = fy + 1.5 * kappa * sy * x
    return 0.4 * fy * dy + fy * x + 0.75 * kappa * sy * x * x - 0.4 * fmax * (dm - dres)


def plastic_work(tape) -> Reading:
    """The plastic work done in all contacts by the end of the run (Thornton's law:
    ``integrate.energies.plastic_work`` of every contact's largest overlap d_max and residual
    overlap at the end), and its partials: on kappa and the yield overlaps (direct), on the final
    residual overlaps (the reverse sweep carries them back to the loading steps), and on d_max,
    the overlap of the step where each contact reached it (state seeds on its two beads'
    positions, found by running the tape again)."""
    from ..integrate.derivatives import differentiate as D
    from ..integrate.core.energies import plastic_work as total

    sy, w = tape.system, tape.packed
    nc = sy.n_contacts
    value = float(total(w.kappa, w.dyield, w.dmax, w.dres))
    yielded = np.flatnonzero(w.dmax[:nc] > w.dyield[:nc])
    if not value > 0.0 or yielded.size == 0:
        raise never(tape, "plastic_work", "no contact passes its yield overlap during the run (none deforms "
                    "plastically); a faster striker (striker.velocity), a longer run (run.duration) or a lower "
                    "materials.NAME.yield_stress would make one")
    args = [w.kappa[yielded], w.dyield[yielded], w.dmax[yielded], w.dres[yielded]]
    grads = []
    for i in range(4):
        z = [a.astype(complex) for a in args]
        z[i] = z[i] + 1j * STEP
        grads.append(_plastic_work(*z).imag / STEP)
    g_kappa, g_dy, g_dm, g_dres = grads
    # the step where each yielded contact's overlap reached its final d_max (first time: the law
    # updates d_max when an overlap exceeds it), and the overlap's partials there (offset beads:
    # d = R_j + R_{j+1} - dist, as plastic.contact_general computes it)
    dmax = w.dmax[yielded]
    found = np.full(yielded.size, -2, dtype=np.int64)
    partials = np.zeros((5, yielded.size))  # d(delta)/d: w = u_j - u_{j+1}, d0, de, dx0, rsum
    de, dx0, rsum, d0 = w.de[yielded], w.dx0[yielded], w.rsum[yielded], w.d0[yielded]
    offset = de != 0.0

    def overlap(wj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        dx = dx0 - wj
        dist = np.sqrt(dx * dx + de * de)
        return np.where(offset, rsum - dist, wj + d0), np.where(offset, dx / dist, 1.0)

    def reached(first: int, wj: np.ndarray) -> None:
        delta, c = overlap(wj)
        hit = (delta == dmax) & (found == -2)
        rows = np.argmax(hit, axis=0)
        new = hit[rows, np.arange(yielded.size)]
        found[new] = first + rows[new]
        c = c[rows, np.arange(yielded.size)]
        dist = np.sqrt((dx0 - wj[rows, np.arange(yielded.size)]) ** 2 + de * de)
        partials[:, new] = np.array([c, np.where(offset, 0.0, 1.0), np.where(offset, -de / dist, 0.0),
                                     np.where(offset, -c, 0.0), np.where(offset, 1.0, 0.0)])[:, new]

    u0 = tape.u0
    reached(-1, (u0[yielded] - u0[yielded + 1])[None, :])
    for first, u, _, _ in D.replay_groups(tape, tape.n_steps - 1):
        reached(first, u[:, yielded] - u[:, yielded + 1])
    if np.any(found == -2):
        raise RuntimeError("the largest overlaps of the replayed run differ from the taped run's")
    size = sy.kappa.size
    d_kappa, d_dyield, final = (np.zeros(size) for _ in range(3))
    d_kappa[yielded], d_dyield[yielded], final[yielded] = g_kappa, g_dy, g_dres
    direct = {"kappa": d_kappa, "dyield": d_dyield}
    for k, name in enumerate(("d0", "de", "dx0", "rsum"), start=1):
        direct[name] = np.zeros(size)
        direct[name][yielded] = g_dm * partials[k]
    seed = g_dm * partials[0]
    arrays = (np.concatenate([found, found]),
              np.concatenate([D.state_seed(0) + yielded, D.state_seed(0) + yielded + 1]),
              np.concatenate([seed, -seed]))
    return Reading(value, arrays=arrays, direct=direct, final_dres=final)


def residual_overlap_max(tape) -> Reading:
    """The largest permanent overlap a contact is left with at the end of the run (the dent a
    protector keeps; Thornton's residual overlap), and its partial: on that contact's final residual
    overlap (the reverse sweep carries it back to the loading steps that set it). The contact of
    the maximum is held fixed."""
    sy, w = tape.system, tape.packed
    nc = sy.n_contacts
    j = int(np.argmax(w.dres[:nc]))
    if not w.dres[j] > 0.0:
        raise never(tape, "residual_overlap_max", "no contact passes its yield overlap during the run (none keeps a "
                    "dent); a faster striker (striker.velocity), a longer run (run.duration) or a lower "
                    "materials.NAME.yield_stress would make one")
    final = np.zeros(sy.kappa.size)
    final[j] = 1.0
    return Reading(float(w.dres[j]), final_dres=final)
