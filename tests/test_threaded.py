"""One chain on several threads (hertzchain.integrate.drivers.threaded) against the single-thread
Verlet: forces, velocities, positions, the wall peak and the steps bit for bit; the energies,
summed block by block, within 1e-12 of the one-thread sums."""

from __future__ import annotations

import threading
import warnings

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.errors import ElasticLimitWarning, PulseNotReachedWarning
from hertzchain.integrate.drivers import threaded
from hertzchain.integrate.drivers.verlet import run_verlet

#: The documented bound on the energies (block sums added in block order vs one sum).
ENERGY_REL = 1e-12


def _same(one, many) -> None:
    for name in ("contact_force", "max_force", "velocity", "displacement"):
        x, y = getattr(one, name), getattr(many, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert np.array_equal(x, y), name
    assert (one.peak_wall_force, one.peak_wall_time, one.n_steps, one.dt, one.dt_max) == (
        many.peak_wall_force, many.peak_wall_time, many.n_steps, many.dt, many.dt_max)
    for name in ("kinetic_energy", "potential_energy"):
        x, y = getattr(one, name), getattr(many, name)
        scale = np.abs(x).max()
        assert np.abs(x - y).max() <= ENERGY_REL * scale, name
    assert np.array_equal(one.dissipated_energy, many.dissipated_energy)


@pytest.mark.parametrize("threads", [2, 3])
def test_long_chain_lean_loop_matches_one_thread(threads):
    """5,000 beads: the lean loop (no forces stored between block ends), blocks of ~1,700 slots."""
    model = hc.Model(hc.Chain.uniform(5000, 26e-3), hc.Striker(8e-3, 0.5))
    s = model.system()
    rec = np.array([0, 1, 2, 1700, 1701, 5000])
    kw = dict(contacts=rec, record_velocities=True)
    _same(run_verlet(s, 4e-5, 1e-7, **kw), threaded.run_verlet_threaded(s, 4e-5, 1e-7, threads, **kw))


# Three threads on the two cores of CI wait at every step's barrier for a scheduler slice: the
# taper case stays in the default run, the other three (13-26 s each) in the slow set.
@pytest.mark.parametrize("case", ["taper", *(pytest.param(c, marks=pytest.mark.slow)
                                            for c in ("precompressed", "fixed_dt", "free_end"))])
def test_pulse_through_blocks_and_wall_peak(case, monkeypatch):
    """A 60-bead chain cut into 3 blocks of ~24 slots (the minimum lowered for the test): the pulse
    crosses both block edges and is reflected by the wall, whose peak the last block tracks."""
    monkeypatch.setattr(threaded, "MIN_SLOTS_PER_THREAD", 8)
    d = np.concatenate([np.full(40, 10e-3), np.geomspace(10e-3, 5e-3, 20)])
    pre = 5.0 if case == "precompressed" else 0.0
    model = hc.Model(hc.Chain.from_diameters(d), hc.Striker(8e-3, 0.3),
                     hc.Wall("none" if case == "free_end" else "flat"), precompression=pre)
    s = model.system()
    dt = 1e-8 if case == "fixed_dt" else None
    kw = dict(dt=dt, record_velocities=True, record_positions=True)
    duration = hc.auto_duration(model)
    one = run_verlet(s, duration, 1e-6, **kw)
    many = threaded.run_verlet_threaded(s, duration, 1e-6, 3, **kw)
    _same(one, many)
    # the pulse reached the end (the wall's contact, or the last bead's free end)
    assert one.max_force[-1 if case != "free_end" else -2] > 0.1 * one.max_force[1]
    if case != "free_end":
        assert one.peak_wall_force > 0.0


def test_simulate_threads_option():
    warnings.simplefilter("ignore", ElasticLimitWarning)
    warnings.simplefilter("ignore", PulseNotReachedWarning)
    model = hc.Model(hc.Chain.uniform(3000, 20e-3), hc.Striker(8e-3, 0.3))
    probes = hc.Probes(contacts=(0, 1000, 2000))
    one = hc.simulate(model, 3e-5, probes, integrator="verlet")
    two = hc.simulate(model, 3e-5, probes, integrator="verlet", threads=2)
    assert np.array_equal(one.contact_force.values, two.contact_force.values)
    assert one.attrs["n_steps"] == two.attrs["n_steps"]
    e1, e2 = one.kinetic_energy.values, two.kinetic_energy.values
    assert np.abs(e1 - e2).max() <= ENERGY_REL * np.abs(e1).max()


def test_refusals():
    body = hc.Model(hc.Chain.uniform(5, 10e-3), hc.Striker(8e-3, 0.2), hc.Wall("body", mass=1.0, stiffness=1e6))
    with pytest.raises(hc.ConfigError, match="run.threads") as exc:  # the threaded engine runs no protected body
        hc.simulate(body, 1e-4, threads=2)
    assert "wall.type" in exc.value.message
    with pytest.raises(hc.ConfigError, match="run.threads"):
        threaded.run_verlet_threaded(body.system(), 1e-4, 1e-6, 2)
    elastic = hc.Model(hc.Chain.uniform(5, 10e-3), hc.Striker(8e-3, 0.2))
    with pytest.raises(hc.ConfigError, match="run.threads"):  # rkn4's threads: aligned elastic chains
        hc.simulate(hc.Model(elastic.chain, elastic.striker, law=hc.Dashpot(20.0)), 1e-4, integrator="rkn4", threads=2)
    with pytest.raises(hc.ConfigError, match="run.threads"):
        hc.simulate(elastic, 1e-4, integrator="dop853", threads=2)
    with pytest.raises(hc.ConfigError, match="run.threads"):
        hc.simulate(elastic, 1e-4, threads=0)


def test_split_is_even_and_cache_line_aligned():
    b = threaded.split(4096, 3)
    assert b[0] == 0 and b[-1] == 4096 and np.all(b % 8 == 0)
    assert np.ptp(np.diff(b)) <= 8


def test_barrier_orders_memory():
    """Three threads pass values around a ring through a barrier 20,000 times: every read sees the
    neighbour's write of the same round (a missing acquire/release would show stale rounds)."""
    from numba import njit

    from hertzchain.integrate.core.barrier import barrier, new_barrier

    @njit(nogil=True)
    def ring(bar, n, me, box, rounds):
        sense = 0
        bad = 0
        for r in range(1, rounds + 1):
            box[me] = r
            sense = barrier(bar, n, sense)
            bad += box[(me + 1) % n] != r
            sense = barrier(bar, n, sense)
        return bad

    n, rounds = 3, 20_000
    bar, box = new_barrier(), np.zeros(n, dtype=np.int64)
    bad = [None] * n

    def go(me):
        bad[me] = ring(bar, n, me, box, rounds)

    ring(new_barrier(), 1, 0, np.zeros(1, dtype=np.int64), 1)  # compile first
    workers = [threading.Thread(target=go, args=(i,)) for i in range(n)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    assert bad == [0, 0, 0]
