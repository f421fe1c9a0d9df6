"""The fast path of a metrics-only ensemble: the batched fourth-order engine (integrate/batch/rkn.py)
is the single run of ``integrate="rkn4"`` member by member, its largest contact forces over the run
bound the sampled ones, the compiled pulse fit (analysis/pulse_batch.py) is ``fit_pulse``'s, and a
sweep's metrics are those of single runs of the same drawn members."""

from __future__ import annotations

import copy
import math
import warnings

import numpy as np
import pytest
from test_ensemble import DURATION, INTERVAL, ensembles

from hertzchain import Probes, simulate
from hertzchain.analysis import fit_pulse
from hertzchain.analysis.pulse import cos6_pulse
from hertzchain.analysis.pulse_batch import PULSE_COLUMNS, fit_pulses
from hertzchain.errors import ConfigError
from hertzchain.runs.batch import simulate_batch
from hertzchain.sweep import parse_sweep, run_sweep
from hertzchain.sweep.runner import F_M_REFINE

RKN_KINDS = ("misaligned", "viscoelastic", "dashpot_free_end")


@pytest.fixture(scope="module")
def rkn_runs():
    """Ensembles the fourth-order engine runs (offsets, Kuwabara-Kono, a dashpot on a free end):
    the batch with every contact sampled, the batch keeping the run's maxima, and single runs."""
    out = {}
    probes = Probes(sample_interval=INTERVAL)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for kind in RKN_KINDS:
            ens = ensembles()[kind]
            out[kind] = (ens, simulate_batch(ens, DURATION, probes, integrator="rkn4"),
                         simulate_batch(ens, DURATION, probes, integrator="auto", max_force="run"),
                         [simulate(ens.model(i), DURATION, probes, integrator="rkn4") for i in range(ens.n_members)])
    return out


@pytest.mark.parametrize("kind", RKN_KINDS)
def test_batched_rkn4_members_are_the_single_rkn4_runs(rkn_runs, kind):
    ens, batch, _, singles = rkn_runs[kind]
    assert batch.attrs["integrator"] == "rkn4"
    for i, single in enumerate(singles):
        for var in ("contact_force", "kinetic_energy", "potential_energy", "dissipated_energy", "max_contact_force"):
            np.testing.assert_array_equal(batch[var].values[i], single[var].values, err_msg=f"{kind} {var} {i}")
        assert float(batch["n_steps"][i]) == single.attrs["n_steps"]
        if ens.has_wall:
            assert float(batch["peak_wall_force"][i]) == single.attrs["peak_wall_force"]


@pytest.mark.parametrize("kind", RKN_KINDS)
def test_maxima_over_the_run_bound_the_sampled_ones_and_change_nothing_else(rkn_runs, kind):
    """``max_force="run"``: step ends and in-step maxima of the same interpolants instead of the
    samples: never below the sampled maxima, above them by less than a force's curvature over one
    sample interval (1 us here, pulses of ~20 us: (pi / 20)^2 / 2 ~ 1e-2 at most, ~1e-4 seen)."""
    _, batch, run, _ = rkn_runs[kind]
    assert run.attrs["integrator"] == "rkn4"  # "auto" picks it for these members
    sampled, over_run = batch["max_contact_force"].values, run["max_contact_force"].values
    assert np.all(over_run >= sampled * (1 - 1e-12))
    assert np.all(over_run <= sampled * (1 + 1e-2))
    for var in ("contact_force", "kinetic_energy", "potential_energy", "dissipated_energy"):
        np.testing.assert_array_equal(run[var].values, batch[var].values)


def test_run_maxima_agree_with_a_finely_sampled_run(rkn_runs):
    """The run's maxima are the forces' true maxima: within 1e-6 of a run sampled every 10 ns."""
    ens, _, run, _ = rkn_runs["misaligned"]
    fine = simulate(ens.model(0), DURATION, Probes(sample_interval=1e-8, contacts=None), integrator="rkn4")
    np.testing.assert_allclose(run["max_contact_force"].values[0], fine["max_contact_force"].values, rtol=1e-6)


def test_rkn4_refuses_what_it_does_not_run():
    ens = ensembles()["elastic"]  # aligned elastic: the symplectic rkn4 of single runs, not batched
    with pytest.raises(ConfigError, match="integrator"):
        simulate_batch(ens, DURATION, Probes(sample_interval=INTERVAL), integrator="rkn4")
    with pytest.raises(ConfigError, match="max_force"):
        simulate_batch(ens, DURATION, Probes(sample_interval=INTERVAL), max_force="all")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = simulate_batch(ens, DURATION, Probes(sample_interval=INTERVAL), integrator="auto")
    assert ds.attrs["integrator"] == "verlet"


def _records(rng, n: int, k: int = 4000, dt: float = 1e-7):
    """Noise-free cos^6 pulses with a smaller second pulse behind and a tail, random F_m, T, tau."""
    t = np.arange(k) * dt
    f_m, tof, tau = rng.uniform(5, 15, n), rng.uniform(1.2e-4, 2.2e-4, n), rng.uniform(1.5e-5, 4e-5, n)
    force = np.array([cos6_pulse(t, a, b, c) + cos6_pulse(t, 0.3 * a, b + 4 * c, 2 * c) for a, b, c in zip(f_m, tof, tau)])
    return t, force


@pytest.mark.parametrize("refine", [1, F_M_REFINE])
def test_compiled_fits_are_fit_pulses(refine):
    """Every record's F_m, T, tau, Q_F, Q_T as fit_pulse's (scipy's Levenberg-Marquardt on every
    window, 50 window updates where the window cycles): within 1e-8, the solvers' convergence."""
    t, force = _records(np.random.default_rng(3), 24)
    values, status = fit_pulses(t, force, refine=refine)
    assert np.all(status == 0)
    for i in range(force.shape[0]):
        ref = fit_pulse(t, force[i], refine=refine)
        np.testing.assert_allclose(values[i], [getattr(ref, c) for c in PULSE_COLUMNS], rtol=1e-8, atol=0)


def test_irregular_records_are_left_to_fit_pulse():
    t, force = _records(np.random.default_rng(4), 3)
    force[0] = np.minimum(force[0], 0.6 * force[0].max())  # clipped: a flat top
    force[1] = 1e-3 * np.random.default_rng(5).standard_normal(t.size)  # noise only
    force[2, -5:] = np.nan
    values, status = fit_pulses(t, force)
    assert np.all(status == 1) and np.all(np.isnan(values))


# Chain 1 of the tolerance example, a few members, its own duration and sampling.
def _example(n: int, chunk_size: int) -> dict:
    import tomllib
    from pathlib import Path

    spec = tomllib.loads((Path(__file__).parents[1] / "examples" / "tolerance_ensemble.toml").read_text())
    spec["sweep"].update(n=n, chunk_size=chunk_size, store="metrics")
    return copy.deepcopy(spec)


def test_sweep_metrics_are_those_of_single_runs_of_the_drawn_members(tmp_path):
    """hertzchain sweep (metrics only) against simulate() with the defaults (integrator "auto": rkn4
    for the offset beads) and fit_pulse on each member alone, scipy's fit on every window update:
    the pulse metrics within 1e-8 (the same records; the fit's solvers), force_over_yield within
    1e-5 (the run's maximum against the samples'), the energies at the end exactly. Member 0's
    window cycles between two sample sets (50 updates in fit_pulse; resolved by parity in the
    compiled fit)."""
    spec = _example(4, 2)
    result = run_sweep(spec, tmp_path)
    cfg = parse_sweep(spec)
    probes = Probes(sample_interval=spec["base"]["run"]["sample_interval"], contacts=())
    df = result.metrics.set_index("member")
    cycling = 0
    for i in range(cfg.n_members):
        model = cfg.member_model(i)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = simulate(model, spec["base"]["run"]["duration"], probes)
        assert ds.attrs["integrator"] == "rkn4"
        fit = fit_pulse(ds["time"].values, ds["wall_force"].values, refine=F_M_REFINE)
        cycling += fit.iterations == 50
        row = df.loc[i]
        for col, attr in (("F_m", "peak_force"), ("T", "time_of_flight"), ("tau", "duration"),
                          ("Q_F", "front_momentum"), ("Q_T", "tail_momentum")):
            assert math.isclose(row[col], getattr(fit, attr), rel_tol=1e-8), (i, col)
        assert row["kinetic_energy_end"] == float(ds["kinetic_energy"].values[-1])
        ratio = np.nanmax(ds["max_contact_force"].values / ds["yield_force"].values)
        assert ratio <= row["force_over_yield"] <= ratio * (1 + 1e-5)
    assert cycling  # the parity shortcut was taken and agrees


@pytest.mark.slow
def test_sweep_metrics_are_within_1e5_of_a_fine_reference(tmp_path):
    """The accuracy of the fast path: each member's metrics against rkn4 at a thousandth of its
    default step tolerance (rtol 1e-9) and the same fit: F_m, T, tau, Q_F, Q_T within 1e-5
    relative (measured on 8 members: <= 1.3e-6, tau; F_m 1.7e-7)."""
    spec = _example(6, 3)
    result = run_sweep(spec, tmp_path)
    cfg = parse_sweep(spec)
    probes = Probes(sample_interval=spec["base"]["run"]["sample_interval"], contacts=())
    df = result.metrics.set_index("member")
    for i in range(cfg.n_members):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = simulate(cfg.member_model(i), spec["base"]["run"]["duration"], probes, integrator="rkn4", rtol=1e-9)
        fit = fit_pulse(ds["time"].values, ds["wall_force"].values, compiled=True, refine=F_M_REFINE)
        for col, attr in (("F_m", "peak_force"), ("T", "time_of_flight"), ("tau", "duration"),
                          ("Q_F", "front_momentum"), ("Q_T", "tail_momentum")):
            assert math.isclose(df.loc[i, col], getattr(fit, attr), rel_tol=1e-5), (i, col)


@pytest.mark.skipif(not hasattr(__import__("mmap"), "MADV_NOHUGEPAGE"), reason="records are mapped on Linux only")
def test_record_pages_are_reused_only_once_their_arrays_are_gone():
    """A batch's record mapping is reused by the next batch of that size (no fresh page faults)
    only when no array of it is left: live results are never written over."""
    from hertzchain.integrate.batch.buffers import _records, release_records

    release_records()
    a = _records(600, 1000)  # 4.8 MB: mapped
    a[:] = 1.0
    b = _records(600, 1000)
    assert not np.shares_memory(a, b)
    address = a.ctypes.data
    del a
    c = _records(600, 1000, zeros=True)
    assert c.ctypes.data == address and not c.any()  # a's pages, zeroed as asked
    view = c[10:20]
    del c
    d = _records(600, 1000)
    d[:] = 2.0
    assert not np.shares_memory(d, view) and not view.any()
    release_records()


def test_quintic_bound_holds_over_the_step_and_skips_open_contacts():
    """``quintic_at_most``: where it says the overlap's quintic Hermite stays at or below a level
    (the probes then write 0 without interpolating), a dense evaluation of the interpolant never
    exceeds it; an overlap that is clearly open over the step (negative, moving apart) is found so,
    and one that closes inside the step is not."""
    from hertzchain.integrate.drivers.rkn_kernels import quintic, quintic_at_most

    rng = np.random.default_rng(7)
    theta = np.linspace(0.0, 1.0, 2001)
    found = 0
    for _ in range(2000):
        h = 10 ** rng.uniform(-9, -6)
        y0, y1 = -(10 ** rng.uniform(-10, -6, 2))
        s0, s1, c0, c1 = rng.normal(size=4) * np.array([1e-3, 1e-3, 1e3, 1e3]) * 10 ** rng.uniform(-3, 3, 4)
        w = np.array(quintic(theta, h))
        p = w.T @ np.array([y0, s0, c0, y1, s1, c1])
        if quintic_at_most(y0, s0, c0, y1, s1, c1, h, 0.0):
            found += 1
            assert p.max() <= 0.0
    assert found > 200
    assert quintic_at_most(-1e-6, -1e-3, 0.0, -2e-6, -1e-3, 0.0, 1e-6, 0.0)  # open, moving apart
    assert quintic_at_most(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1e-6, 0.0)  # at rest, untouched: exactly 0
    assert not quintic_at_most(-1e-9, 1e-3, 0.0, 1e-9, 1e-3, 0.0, 2e-6, 0.0)  # closes inside the step


def test_quickselect_quantiles_are_numpys_bit_for_bit():
    """The compiled fit's own quantile (quickselect, written to spare Numba's ~1-3 s compiles of
    ``np.percentile``/``np.partition``/``np.median``) gives NumPy's linear-method quantile
    exactly: any length, any quantile, ties, sorted and reversed inputs; the scratch copy keeps
    every value."""
    from hertzchain.analysis.pulse_batch import _quantile, _select

    rng = np.random.default_rng(5)
    for n in (1, 2, 3, 4, 7, 64, 501):
        for kind in ("uniform", "ties", "sorted", "reversed", "constant"):
            y = {"uniform": rng.normal(size=n), "ties": rng.integers(0, 4, n).astype(float),
                 "sorted": np.sort(rng.normal(size=n)), "reversed": np.sort(rng.normal(size=n))[::-1].copy(),
                 "constant": np.full(n, 2.5)}[kind]
            for q in (0.0, 0.1, 0.25, 0.5, 0.75, 0.999, 1.0):
                w = y.copy()
                assert _quantile(w, q) == np.quantile(y, q), (n, kind, q)
                assert np.array_equal(np.sort(w), np.sort(y))
            k = int(rng.integers(0, n))
            w = y.copy()
            assert _select(w, k) == np.sort(y)[k] and w[k + 1:].min(initial=np.inf) >= w[k]


def test_fit_shortcuts_give_numpys_order_statistics_and_one_pass_momenta():
    """The compiled fit's shortcuts for a record mostly at one value (a wall before its pulse):
    the 10th percentile and the median are NumPy's exactly, whether or not the shortcut applies,
    and the front and tail momenta of one pass are those of two separate trapezoid sums."""
    from hertzchain.analysis.pulse_batch import _median, _momenta, _percentile_10

    rng = np.random.default_rng(11)
    for zeros in (0, 5, 50, 90, 99):
        y = rng.uniform(0.1, 2.0, 200)
        y[rng.permutation(200)[:2 * zeros]] = 0.0
        assert _percentile_10(y) == np.percentile(y, 10)
        assert _median(y) == np.median(y) and _median(y[:-1]) == np.median(y[:-1])
    t = np.sort(rng.uniform(0.0, 1.0, 300))
    f = rng.normal(size=300)
    for split in (-1.0, t[0], t[7], 0.5 * (t[100] + t[101]), t[-1], 2.0):
        front, tail = _momenta(t, f, 0.1, split)
        k = np.searchsorted(t, split, side="right")
        ref_total = float(np.sum(0.5 * ((f[:-1] - 0.1) + (f[1:] - 0.1)) * np.diff(t)))
        if t[0] < split < t[-1]:
            fs = np.interp(split, t, f - 0.1)
            ref_front = float(np.sum(0.5 * ((f[:k - 1] - 0.1) + (f[1:k] - 0.1)) * np.diff(t[:k]))
                              + 0.5 * ((f[k - 1] - 0.1) + fs) * (split - t[k - 1]))
        else:
            ref_front = 0.0 if split <= t[0] else ref_total
        assert front == pytest.approx(ref_front, rel=1e-12, abs=1e-15)
        assert front + tail == pytest.approx(ref_total, rel=1e-12)


@pytest.mark.parametrize("law", ["elastic", "viscoelastic", "dashpot"])
def test_force_bound_holds_over_the_step(law):
    """``force_bound``: the run's maxima search a step only where its bound passes the maximum so
    far; no force the probes interpolate in the step (the law at the interpolated overlap and rate,
    dense in theta) exceeds it, and it is close to the largest one for a loaded contact."""
    from hertzchain.integrate.core.kernels import LAW_DASHPOT, LAW_VISCOELASTIC
    from hertzchain.integrate.drivers import rkn_damped_kernels as rk
    from hertzchain.integrate.drivers.rkn_kernels import force_bound

    code = LAW_VISCOELASTIC if law == "viscoelastic" else LAW_DASHPOT
    damping = {"elastic": 0.0, "viscoelastic": 2e-6, "dashpot": 5.0}[law]
    kappa = np.array([1e10])
    rng = np.random.default_rng(5)
    theta = np.linspace(0.0, 1.0, 401)
    ratios = []
    for _ in range(300):
        h = 10 ** rng.uniform(-8, -6)
        ed = np.zeros((2, rk.ROWS, 1))
        ed[:, rk.R_D, 0] = rng.uniform(-2e-7, 1e-6, 2)
        ed[:, rk.R_R, 0] = rng.normal(size=2) * 1e-2
        ed[:, rk.R_Q, 0] = rng.normal(size=2) * 1e4
        f = max(rk._force_at(ed, 0, 1, 0, x, h, kappa, np.array([damping]), np.zeros(1), None, code) for x in theta)
        bound = force_bound(*ed[0, rk.R_D:rk.R_Q + 1, 0], *ed[1, rk.R_D:rk.R_Q + 1, 0], h, kappa[0], damping,
                            code == LAW_VISCOELASTIC)
        assert f <= bound
        if f > 0:
            ratios.append(bound / f)
    assert np.median(ratios) < 2.0  # a bound that skips most searches, not just any upper bound
