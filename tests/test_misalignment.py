"""Robustness checks of the paper's Fig. 3 (Melo et al. 2006, Sec. II): off-axis beads (a, b)
and local changes of the tapering factor (c).

Offsets follow docs/conventions.rst (misalignment): bead n sits off the axis by e_n (held by its track), the
distance of centres is d = sqrt(dx^2 + de^2), delta = R_n + R_{n+1} - d and the axial force is
F(delta) dx / d. To first order an offset softens the two contacts of the bead by
(dx0/d0)^(5/2) ~ 1 - (5/4)(de/d0)^2, about 1.2 % for e = 10 % of the bead diameter: the
expected effects are small, as in the paper ("slightly", "nearly unchanged").

Pulse measures are sample-based (no fit): F_m and T from the parabola through the samples
around the maximum of the wall force, the duration tau from the half-maximum rise time (cos^6
is at half its maximum at (t - T)/tau = -arccos(2^(-1/6)) = -0.4715, paper eq. 4), the 10-90 %
rise time and the full width at half maximum.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from hertzchain.chain import Chain, paper_chain
from hertzchain.config import parse_config, run_config
from hertzchain.contact import Viscoelastic
from hertzchain.dissipation import calibrate_law
from hertzchain.model import Model, Striker
from hertzchain.probes import Probes
from hertzchain.runs.simulation import simulate

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
STRIKER = Striker(8e-3, 0.2)  # the paper's striker; forces far below the elastic limit
FRACTIONS = (0.0, 0.025, 0.05, 0.075, 0.10)  # e / phi, up to the paper's 10 %
HALF_MAX_PHASE = math.acos(2.0 ** (-1.0 / 6.0))  # 0.4715


def _crossing(t: np.ndarray, w: np.ndarray, k: int, level: float, step: int) -> float:
    """Time where w crosses ``level`` walking from sample k (the maximum) by ``step`` (-1 or +1)."""
    i = k
    while w[i] > level:
        i += step
    j = i - step  # w[i] <= level < w[j]
    return t[i] + (t[j] - t[i]) * (level - w[i]) / (w[j] - w[i])


def pulse(t: np.ndarray, w: np.ndarray) -> dict:
    """F_m [N], T [s], tau [s], rise time 10-90 % [s] and FWHM [s] of the front pulse."""
    k = int(np.argmax(w))
    # the maximum of these records is the front pulse: nothing before it reaches half of it
    assert np.all(w[: max(k - 2000, 0)] < 0.5 * w[k])
    fb, f0, fa = w[k - 1], w[k], w[k + 1]
    s = 0.5 * (fb - fa) / (fb - 2.0 * f0 + fa)
    fm = f0 - 0.25 * (fb - fa) * s
    T = t[k] + s * (t[1] - t[0])
    t50 = _crossing(t, w, k, 0.5 * fm, -1)
    return {"Fm": fm, "T": T, "tau": (T - t50) / HALF_MAX_PHASE,
            "rise": _crossing(t, w, k, 0.9 * fm, -1) - _crossing(t, w, k, 0.1 * fm, -1),
            "fwhm": _crossing(t, w, k, 0.5 * fm, +1) - t50}


def tail_rms(t: np.ndarray, w: np.ndarray, p: dict, end: float) -> float:
    """RMS of the wall force from T + tau (end of the front pulse, paper Sec. III) to T + end."""
    sel = (t > p["T"] + p["tau"]) & (t < p["T"] + end)
    return float(np.sqrt(np.mean(w[sel] ** 2)))


def tail_peak(t: np.ndarray, w: np.ndarray, p: dict, lo: float = 0.30e-3, hi: float = 0.45e-3) -> float:
    """Height of the paper's "more pronounced peak of the tail (t - T ~ 0.38 ms)": the largest
    local maximum of the wall force with lo < t - T < hi."""
    sel = np.flatnonzero((t > p["T"] + lo) & (t < p["T"] + hi))
    y = w[sel]
    inner = (y[1:-1] > y[:-2]) & (y[1:-1] >= y[2:])
    assert inner.any()
    return float(y[1:-1][inner].max())


def _wall(chain: Chain, law=None, duration: float = 3.5e-3):
    kwargs = {} if law is None else {"law": law}
    # the Verlet for every chain, so that aligned and offset chains are compared on one engine
    ds = simulate(Model(chain, STRIKER, **kwargs), duration, Probes(sample_interval=1e-7, contacts=(chain.n_beads,)),
                  integrator="verlet")
    return ds.time.values, ds.wall_force.values, ds


# ------------------------------------------------------------------------------- zero limit
def test_zero_offsets_are_bit_identical_to_the_aligned_chain():
    chain = paper_chain("chain2")
    zero = chain.with_offsets({22: 0.0, 28: 0.0})
    assert zero.is_aligned
    for law in (None, Viscoelastic(4e-6)):
        _, w_ref, ref = _wall(chain, law, 3e-3)
        _, _, off = _wall(zero, law, 3e-3)
        assert np.array_equal(off.contact_force.values, ref.contact_force.values)
        assert w_ref.max() > 2.0
    # the same through a config file's offsets_fraction
    cfg = {"chain": {"preset": "chain2"}, "striker": {"diameter_mm": 8.0, "velocity": 0.2},
           "run": {"duration": 3e-3, "sample_interval": 1e-6}}
    a = run_config(cfg)
    cfg["chain"]["offsets_fraction"] = [0.0] * 28
    b = run_config(cfg)
    assert np.array_equal(a.contact_force.values, b.contact_force.values)


def test_tiny_offset_is_continuous_with_the_aligned_chain():
    """e = 100 nm goes through the oblique-contact branch (results differ from the aligned run)
    yet changes the contacts' stiffness by only (5/4)(e/d0)^2 ~ 5e-11."""
    chain = paper_chain("chain2")
    _, w0, _ = _wall(chain, duration=3e-3)
    _, w1, _ = _wall(chain.with_offsets({22: 1e-7}), duration=3e-3)
    assert not np.array_equal(w0, w1)
    assert np.max(np.abs(w1 - w0)) < 1e-8 * w0.max()


# ------------------------------------------------------------------------------- Fig. 3a-b
@pytest.fixture(scope="module")
def offset_runs():
    """Wall force of the FULL chain 2 with bead 22 (16 mm) or bead 28 (9 mm, touching the wall)
    off the axis by e = 0 .. 10 % of its diameter (paper Fig. 3a, 3b)."""
    chain = paper_chain("chain2")
    out = {}
    for bead in (22, 28):
        phi = chain.diameters[bead - 1]
        out[bead] = [_wall(chain.with_offsets({bead: f * phi}))[:2] for f in FRACTIONS]
    return out


def test_fig3a_offset_in_the_middle_of_the_taper(offset_runs):
    """Bead 22 (phi = 16 mm) off axis, paper Fig. 3a: "the signal decreases slightly in amplitude
    and the oscillations of the tail progressively decrease ... the more pronounced peak of the
    tail (t - T ~ 0.38 ms) is progressively decreasing in amplitude"; "the front pulse velocity
    is nearly unchanged". Measured at e = 10 %: F_m -0.02 %, tail rms -0.16 %, tail peak at
    0.37 ms -1.1 %, T +0.03 %.
    """
    runs = offset_runs[22]
    p = [pulse(t, w) for t, w in runs]
    fm = np.array([q["Fm"] for q in p])
    assert np.all(np.diff(fm) < 0) and fm[-1] > 0.99 * fm[0]  # decreases, slightly
    # tail oscillations weaken: RMS after the front pulse, for any window end from 0.4 to 1 ms
    for end in (0.4e-3, 0.5e-3, 0.6e-3, 0.8e-3, 1.0e-3):
        rms = np.array([tail_rms(t, w, q, end) for (t, w), q in zip(runs, p)])
        assert np.all(np.diff(rms) < 0), (end, rms)
    peak = np.array([tail_peak(t, w, q) for (t, w), q in zip(runs, p)])
    assert np.all(np.diff(peak) < 0) and peak[-1] < 0.995 * peak[0]
    T = np.array([q["T"] for q in p])
    assert np.all(np.abs(T / T[0] - 1) < 1e-3)  # time of flight nearly unchanged


def test_fig3b_offset_of_the_bead_touching_the_wall(offset_runs):
    """Bead 28 (phi = 9 mm, touching the wall sensor) off axis, paper Fig. 3b: "a misalignment up
    to 10 % at the end chain does not introduce dramatic effect on the wave. The amplitude is
    slightly modified and only some effects take place at the tail". Measured at e = 10 %: F_m
    -0.07 % (monotonic), T +0.006 %, tail rms (T + tau .. T + 0.5 ms) +0.13 %.

    The paper claims no sign for this tail; in the model it does NOT weaken monotonically (the
    RMS rises slightly for most windows), so only its smallness is asserted.
    """
    runs = offset_runs[28]
    p = [pulse(t, w) for t, w in runs]
    fm = np.array([q["Fm"] for q in p])
    assert np.all(np.diff(fm) < 0) and fm[-1] > 0.99 * fm[0]
    T = np.array([q["T"] for q in p])
    assert np.all(np.abs(T / T[0] - 1) < 1e-3)
    for end in (0.4e-3, 0.5e-3, 0.6e-3, 0.8e-3, 1.0e-3):
        rms = np.array([tail_rms(t, w, q, end) for (t, w), q in zip(runs, p)])
        assert np.all(np.abs(rms / rms[0] - 1) < 5e-3), (end, rms)


def test_fig3a_with_calibrated_dissipation():
    """Bead 22 again with the Kuwabara-Kono law calibrated to eps = 0.985 (paper Sec. III).

    The tail still weakens as the paper reports, but the amplitude no longer decreases: it rises
    by +0.004 % at e = 10 % (softer contacts make the pulse a little longer, and the loss per bead
    ~ A / tau a little smaller, which outweighs the elastic -0.02 %). Only its smallness is
    asserted here.
    """
    chain = paper_chain("chain2")
    law = calibrate_law("viscoelastic", 0.985, chain=chain, striker=STRIKER)
    runs = [_wall(chain.with_offsets({22: f * 16e-3}), law)[:2] for f in (0.0, 0.05, 0.10)]
    p = [pulse(t, w) for t, w in runs]
    fm = np.array([q["Fm"] for q in p])
    assert np.all(np.abs(fm / fm[0] - 1) < 1e-4)
    rms = np.array([tail_rms(t, w, q, 0.5e-3) for (t, w), q in zip(runs, p)])
    assert np.all(np.diff(rms) < 0)
    peak = np.array([tail_peak(t, w, q) for (t, w), q in zip(runs, p)])
    assert np.all(np.diff(peak) < 0)


# ------------------------------------------------------------------------------- Fig. 3c
def _fig3c(name: str, law: str | None = None):
    data = tomllib.loads((EXAMPLES / f"fig3c_{name}.toml").read_text())
    if law is not None:
        data["contact"] = {"law": law} if law == "elastic" else {"law": law, "eps": 0.985}
    ds = run_config(parse_config(data))
    return ds


@pytest.mark.parametrize("law", [None, "elastic", "dashpot"])
def test_fig3c_local_taper_changes(law):
    """Paper Fig. 3c (reading of docs/guide/reproduction.rst (section "Fig. 3c")): "for dq/q = +1, the front pulse is
    slightly steeper and narrower. In contrast, for dq/q = -1, a smoother and slightly wider front
    pulse is produced." ``law=None`` runs the example configs as they are (the reproduction's
    size-scaled dashpot calibrated to eps = 0.985); the elastic and dashpot variants show the
    effect is geometric. Measured (size-scaled dashpot): rise 10-90 % -0.12 % / +0.32 %, FWHM
    -0.27 % / +0.66 %.
    """
    runs = {name: _fig3c(name, law) for name in ("reference", "dq_plus", "dq_minus")}
    d = {name: runs[name].diameter.values * 1e3 for name in runs}
    assert d["reference"].size == 24
    assert list(d["dq_plus"][16:20]) == [24.0, 22.0, 22.0, 21.0]
    assert list(d["dq_minus"][16:20]) == [24.0, 23.0, 23.0, 21.0]
    p = {name: pulse(ds.time.values, ds.wall_force.values) for name, ds in runs.items()}
    ref, plus, minus = p["reference"], p["dq_plus"], p["dq_minus"]
    # dq/q = +1: steeper and narrower
    assert plus["rise"] < ref["rise"] and plus["fwhm"] < ref["fwhm"] and plus["tau"] < ref["tau"]
    # dq/q = -1: smoother and wider
    assert minus["rise"] > ref["rise"] and minus["fwhm"] > ref["fwhm"] and minus["tau"] > ref["tau"]
    # "slightly": a fraction of a per cent
    for q in (plus, minus):
        for key in ("rise", "fwhm", "tau"):
            assert abs(q[key] / ref[key] - 1) < 1e-2


def test_fig3c_caption_literal_reading_is_no_change():
    """The caption's "bead 18 replaced by phi_18 = phi_19 = 23.0 mm" is Table I's own bead 18:
    read literally it changes nothing, which is why docs/guide/reproduction.rst (section "Fig. 3c") does not use it."""
    data = tomllib.loads((EXAMPLES / "fig3c_reference.toml").read_text())
    data["contact"] = {"law": "elastic"}
    data["run"]["duration"] = 2.5e-3
    ref = run_config(parse_config(data))
    data["chain"]["substitutions"] = [{"bead": 18, "diameter_mm": 23.0}]
    lit = run_config(parse_config(data))
    assert np.array_equal(ref.wall_force.values, lit.wall_force.values)
