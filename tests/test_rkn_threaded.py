"""The fourth-order integrator on several threads (hertzchain.integrate.drivers.rkn_threaded)
against one thread: velocities, positions and the step sequence bit for bit (the same per-body
arithmetic, the step a maximum over blocks); the interpolated forces, the largest forces, the wall
peak and the energies within 1e-12 (the end data's reassociated arithmetic, the energies' block
sums); and threads="auto"."""

from __future__ import annotations

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.engine_choice import AUTO_THREADS_MIN_BEADS, choose_engine
from hertzchain.integrate.drivers import rkn_threaded, threaded
from hertzchain.integrate.drivers.rkn import run_rkn

#: The documented bound on what is not bit for bit (module docstring), relative to the largest value.
REL = 1e-12


def _same(one, many) -> None:
    for name in ("velocity", "displacement"):
        assert np.array_equal(getattr(one, name), getattr(many, name)), name
    assert (one.n_steps, one.dt, one.dt_max) == (many.n_steps, many.dt, many.dt_max)
    for name in ("contact_force", "max_force", "kinetic_energy", "potential_energy"):
        x, y = getattr(one, name), getattr(many, name)
        assert np.abs(x - y).max() <= REL * np.abs(x).max(), name
    assert abs(one.peak_wall_force - many.peak_wall_force) <= REL * one.peak_wall_force
    assert abs(one.peak_wall_time - many.peak_wall_time) <= REL * one.peak_wall_time


@pytest.mark.parametrize("case", ["taper", "precompressed", "fixed_dt", "free_end", "switching"])
def test_pulse_through_blocks_and_wall_peak(case, monkeypatch):
    """A 24-bead chain cut into 2 blocks of 16 and 8 slots (the minimum lowered for the test): the
    pulse crosses the block edge and is reflected by the wall, whose peak the last block tracks;
    every chunk on the threads, or (``switching``) alternately on the threads and on one (the
    fallback on shared cores). Short runs: on shared cores every barrier may wait for a slice."""
    monkeypatch.setattr(rkn_threaded, "MIN_SLOTS_PER_THREAD", 8)
    monkeypatch.setattr(rkn_threaded, "RKN_CHUNK_BEAD_STEPS", 2e3)  # many chunks
    calls = []

    def pace(self):  # the threads on every chunk, or (switching) alternately the threads and one
        calls.append(1 if case == "switching" and len(calls) % 2 else self.threads)
        return calls[-1]

    monkeypatch.setattr(threaded.Pace, "next", pace)
    d = np.concatenate([np.full(16, 10e-3), np.geomspace(10e-3, 5e-3, 8)])
    pre = 5.0 if case == "precompressed" else 0.0
    model = hc.Model(hc.Chain.from_diameters(d), hc.Striker(8e-3, 0.3),
                     hc.Wall("none" if case == "free_end" else "flat"), precompression=pre)
    s = model.system()
    dt = 2e-7 if case == "fixed_dt" else None
    kw = dict(dt=dt, record_velocities=True, record_positions=True, rtol=1e-5)
    duration = hc.auto_duration(model)
    one = run_rkn(s, duration, 1e-6, **kw)
    many = run_rkn(s, duration, 1e-6, threads=2, **kw)
    _same(one, many)
    # the pulse reached the end (the wall's contact, or the last bead's free end)
    assert one.max_force[-1 if case != "free_end" else -2] > 0.1 * one.max_force[1]
    if case != "free_end":
        assert one.peak_wall_force > 0.0
    assert set(calls) == ({1, 2} if case == "switching" else {2})


def test_auto_threads_on_the_rkn4_path():
    """threads="auto": the default integrator (rkn4) of a long aligned elastic chain gets the free
    cores, none when they are busy or the chain is short; the other rkn4 paths run on one thread."""
    long = hc.Model(hc.Chain.uniform(AUTO_THREADS_MIN_BEADS, 10e-3), hc.Striker(8e-3, 0.3)).system()
    c = choose_engine(long, cores=2, load=0.0)
    assert (c.integrator, c.threads) == ("rkn4", 2)
    assert choose_engine(long, cores=2, load=3.0).threads == 1  # two cores, other work on both
    assert choose_engine(long, cores=1, load=0.0).threads == 1
    short = hc.Model(hc.Chain.uniform(AUTO_THREADS_MIN_BEADS - 1, 10e-3), hc.Striker(8e-3, 0.3)).system()
    assert choose_engine(short, cores=2, load=0.0).threads == 1
    damped = hc.Model(hc.Chain.uniform(AUTO_THREADS_MIN_BEADS, 10e-3), hc.Striker(8e-3, 0.3),
                      law=hc.Dashpot(gamma=20.0)).system()
    c = choose_engine(damped, cores=2, load=0.0)
    assert (c.integrator, c.threads) == ("rkn4", 1)
    # asked for: rkn4 on two threads where it runs them, refused (naming run.threads) where not
    assert choose_engine(long, "rkn4", 2).threads == 2
    with pytest.raises(hc.ConfigError, match="run.threads"):
        choose_engine(damped, "rkn4", 2)


@pytest.mark.filterwarnings("ignore::hertzchain.errors.PulseNotReachedWarning")
def test_simulate_default_threads_matches_one_thread(monkeypatch):
    """The default call on a chain auto splits (the machine's cores and load given): rkn4 on two
    threads, the same steps and forces (within REL) as one thread."""
    from hertzchain import engine_choice

    monkeypatch.setattr(engine_choice, "free_cores", lambda: (2, 0.0))
    monkeypatch.setattr(engine_choice, "AUTO_THREADS_MIN_BEADS", 2000)
    monkeypatch.setattr(engine_choice, "BEADS_PER_THREAD", 1000)
    model = hc.Model(hc.Chain.uniform(2000, 10e-3), hc.Striker(8e-3, 0.3))
    probes = hc.Probes(contacts=(0, 1, 2, 1000, 2000))
    two = hc.simulate(model, 1e-4, probes)
    one = hc.simulate(model, 1e-4, probes, threads=1)
    assert (two.attrs["integrator_used"], two.attrs["threads_used"]) == ("rkn4", 2)
    assert (one.attrs["integrator_used"], one.attrs["threads_used"]) == ("rkn4", 1)
    f1, f2 = one.contact_force.values, two.contact_force.values
    assert np.abs(f1 - f2).max() <= REL * np.abs(f1).max()
    assert one.attrs["n_steps"] == two.attrs["n_steps"]
