"""One chain on several threads for every contact law (hertzchain.integrate.drivers.threaded_laws) against
the single-thread Verlet of the same law: forces, velocities, positions, the per-contact state,
the wall peak and the steps bit for bit (the threads compute each contact as the one-thread loop
does); the energies, the dissipated energy and the plastic work, summed block by block, within
1e-12 of the one-thread sums (the documented bound); the energy balance KE + PE + dissipated
(+ plastic work) conserved as the one-thread run conserves it."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.errors import ElasticLimitWarning, PulseNotReachedWarning
from hertzchain.integrate.drivers import threaded
from hertzchain.integrate.drivers.verlet import run_verlet

#: The documented bound on the block sums (energies, dissipated energy, plastic work) against one sum.
SUM_REL = 1e-12
#: 60 beads: 26 mm then a taper to 13 mm (the pulse sharpens; every block edge is crossed).
DIAMETERS = np.concatenate([np.full(40, 26e-3), np.geomspace(26e-3, 13e-3, 20)])
#: Offsets [m] (misaligned pairs, an aligned pair, in every block of 2 or 3 threads).
OFFSETS = {1: 2e-5, 2: -1e-5, 4: 3e-5, 5: 1e-5, 24: -2e-5, 25: -2e-5, 45: 1.5e-5}

LAWS = {
    "elastic": None,
    "viscoelastic": hc.Viscoelastic(A=2e-6),
    "dashpot": hc.Dashpot(gamma=20.0),
    "viscoelastic_scaled": hc.ScaledViscoelastic(5e-6, 26e-3),
    "dashpot_scaled": hc.ScaledDashpot(25.0, 26e-3),
    "elastoplastic": hc.Elastoplastic(A=1e-6),
    "power": hc.PowerLaw(1.7, 2e11),
    "hunt_crossley": hc.HuntCrossley(0.8),
}
#: Run by default: the one-thread fused viscous contact here, a registry law with per-contact
#: state (Hunt-Crossley) in the thread-count switching test below and Thornton's state on offset
#: beads (the general contact); the others in the slow set (each law and geometry compiles its
#: thread function once, ~5 s).
DEFAULT = {"viscoelastic"}
DEFAULT_OFFSETS = {"elastoplastic"}


def _model(name: str, offsets: bool) -> hc.Model:
    chain = hc.Chain.from_diameters(DIAMETERS)
    if offsets:
        chain = chain.with_offsets(OFFSETS)
    kw = {} if LAWS[name] is None else {"law": LAWS[name]}
    # the elastic-plastic contacts yield at ~0.2 m/s between 26 mm beads: 2 m/s makes them
    return hc.Model(chain, hc.Striker(8e-3, 2.0 if name == "elastoplastic" else 0.5), hc.Wall(), **kw)


def _compare(model: hc.Model, threads: int = 3):
    warnings.simplefilter("ignore", ElasticLimitWarning)
    s = model.system()
    duration = hc.auto_duration(model)
    kw = dict(record_velocities=True, record_positions=True)
    one = run_verlet(s, duration, 1e-6, **kw)
    many = threaded.run_verlet_threaded(s, duration, 1e-6, threads, **kw)
    for name in ("contact_force", "max_force", "velocity", "displacement", "max_overlap", "residual_overlap"):
        x, y = getattr(one, name), getattr(many, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert np.array_equal(x, y), name
    assert (one.peak_wall_force, one.peak_wall_time, one.n_steps, one.dt, one.dt_max) == (
        many.peak_wall_force, many.peak_wall_time, many.n_steps, many.dt, many.dt_max)
    sums = ["kinetic_energy", "potential_energy", "dissipated_energy"] + (["plastic_work"] if one.plastic_work
                                                                          is not None else [])
    scale = np.abs(one.kinetic_energy).max()
    for name in sums:
        x, y = getattr(one, name), getattr(many, name)
        assert np.abs(x - y).max() <= SUM_REL * scale, name
    # the energy balance: what the threads conserve is what one thread conserves (to the sums' rounding)
    total = [r.kinetic_energy + r.potential_energy + r.dissipated_energy
             + (0.0 if r.plastic_work is None else r.plastic_work) for r in (one, many)]
    drift_one = np.abs(total[0] - total[0][0]).max() / total[0][0]
    drift_many = np.abs(total[1] - total[1][0]).max() / total[1][0]
    # the adaptive Verlet's documented energy error (verlet.ADAPTIVE_STEPS_PER_RADIAN: below 1e-6;
    # 1e-7 to 3e-7 here for every law)
    assert drift_one < 1e-6, drift_one
    assert abs(drift_many - drift_one) <= 10 * SUM_REL
    return one, many


def _threads(names, default):
    """(law, threads): the default set on 2 threads, the slow set on 3 (a middle block with
    neighbours on both sides). On CI's two cores, shared with the other test worker, 3 threads
    waited at every step's barrier for a descheduled one: 65 s for one test, 6 s on 2 threads."""
    return [pytest.param(n, 2) if n in default else pytest.param(n, 3, marks=pytest.mark.slow) for n in names]


@pytest.mark.parametrize("name, threads", _threads([n for n in LAWS if n != "elastic"], DEFAULT))
def test_every_law_on_several_threads_is_the_one_thread_run(name, threads, monkeypatch):
    """A 60-bead chain cut into blocks of >= 8 slots (the minimum lowered for the test): the pulse
    crosses every block edge and is reflected by the wall, whose peak the last block tracks."""
    monkeypatch.setattr(threaded, "MIN_SLOTS_PER_THREAD", 8)
    one, _ = _compare(_model(name, offsets=False), threads)
    assert one.max_force[-1] > 0.05 * one.max_force[1]  # the pulse reached the wall
    if hc.laws.get_law(name).dissipative:
        assert one.dissipated_energy[-1] + (0.0 if one.plastic_work is None else one.plastic_work[-1]) > 0.0
    if name == "elastoplastic":
        assert one.plastic_work[-1] > 0.0 and one.residual_overlap.max() > 0.0  # the contacts yielded


@pytest.mark.parametrize("name, threads", _threads(("elastic", "dashpot", "elastoplastic", "hunt_crossley"),
                                                  DEFAULT_OFFSETS))
def test_offset_beads_on_several_threads_are_the_one_thread_run(name, threads, monkeypatch):
    """Misaligned beads (the one-thread loop's fused offset steps or the general path): the threads'
    contacts compute the misaligned geometry as it does, on both sides of every block edge."""
    monkeypatch.setattr(threaded, "MIN_SLOTS_PER_THREAD", 8)
    model = _model(name, offsets=True)
    assert model.system().misaligned
    one, _ = _compare(model, threads)
    if name == "elastoplastic":
        assert one.plastic_work[-1] > 0.0


def test_simulate_threads_with_a_registry_law_and_two_threads():
    """``hc.simulate(..., threads=2)`` with Hunt-Crossley on a chain long enough for two blocks of
    the default minimum: the recorded forces and the peak are those of one thread."""
    warnings.simplefilter("ignore", ElasticLimitWarning)
    warnings.simplefilter("ignore", PulseNotReachedWarning)
    model = hc.Model(hc.Chain.uniform(1200, 20e-3), hc.Striker(8e-3, 0.3), law=hc.HuntCrossley(0.8))
    probes = hc.Probes(contacts=(0, 500, 700))
    one = hc.simulate(model, 2e-5, probes, integrator="verlet", threads=1)
    two = hc.simulate(model, 2e-5, probes, threads=2)
    assert two.attrs["threads_used"] == 2
    assert np.array_equal(one.contact_force.values, two.contact_force.values)
    assert one.attrs["n_steps"] == two.attrs["n_steps"]
    assert one.attrs["peak_wall_force"] == two.attrs["peak_wall_force"]


def test_mass_in_mass_beads_are_refused_naming_the_field():
    res = hc.Element("mim", resonator_fraction=0.3, resonator_frequency=5000.0)
    model = hc.Model(hc.Chain([10e-3] * 4, elements=(res,) * 4), hc.Striker(8e-3, 0.2))
    with pytest.raises(hc.ConfigError, match="run.threads") as exc:
        threaded.run_verlet_threaded(model.system(), 1e-4, 1e-6, 2)
    assert "chain.elements" in exc.value.message


# Hunt-Crossley (a law with state, carried across the switches) in the default run, the elastic
# case in the slow set; on 2 threads (see _threads).
@pytest.mark.parametrize("name", [pytest.param("elastic", marks=pytest.mark.slow), "hunt_crossley"])
def test_a_run_that_changes_its_thread_count_is_the_one_thread_run(name, monkeypatch):
    """The fallback to one thread on shared cores (``threaded.Pace``), forced to switch between 2
    threads and 1 from chunk to chunk: forces and steps are still those of one thread bit for bit,
    the blocks' dissipated energy carried across the switches."""
    monkeypatch.setattr(threaded, "MIN_SLOTS_PER_THREAD", 8)
    monkeypatch.setattr(threaded, "CHUNK_BEAD_STEPS", 2e4)  # a chunk a sample or so
    counts = []

    def alternate(self):
        counts.append(2 if self.chunk % 3 else 1)
        return counts[-1]

    monkeypatch.setattr(threaded.Pace, "next", alternate)
    _compare(_model(name, offsets=False), threads=2)
    assert {1, 2} <= set(counts) and len(counts) > 10


def test_the_pace_keeps_the_threads_unless_they_were_descheduled():
    pace = threaded.Pace(2)
    assert pace.next() == 2
    pace.record(2, 1e9, 1.0, 0.99)  # not descheduled: the threads stay
    assert [pace.next() for _ in range(3)] == [2, 2, 2]
    pace.record(2, 1e9, 1.0, 0.5)  # descheduled: one thread is timed
    assert pace.next() == 1
    pace.record(1, 2e9, 1.0, 1.0)  # one thread was faster: it runs ...
    assert pace.next() == 1
    for _ in range(threaded.PROBE_EVERY):
        pace.record(1, 2e9, 1.0, 1.0)
    assert pace.next() == 2  # ... and the threads are timed again later
    assert threaded.Pace(1).next() == 1
