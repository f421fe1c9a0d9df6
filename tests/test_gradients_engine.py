"""The derivative engines (integrate/tape, adjoint, tangent): the taped run is the engine's run bit
for bit, and the reverse sweep and the tangent model, two independent differentiations of the same
steps, give the same derivatives for every System parameter."""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from hertzchain.config import build_model, parse_config
from hertzchain.integrate.derivatives import differentiate as D
from hertzchain.integrate.drivers.verlet import run_verlet

BASE = {"chain": {"diameters_mm": [20.0, 19.0, 18.0, 17.0, 16.0, 15.0, 14.0, 13.0]},
        "striker": {"velocity": 0.3, "diameter_mm": 8.0},
        "run": {"duration": 3e-4, "sample_interval": 1e-7}}


def _cfg(**changes) -> dict:
    cfg = copy.deepcopy(BASE)
    for path, value in changes.items():
        section, key = path.split("__")
        cfg.setdefault(section, {})[key] = value
    return cfg


CASES = {
    "elastic adaptive": _cfg(),
    "elastic coarse": _cfg(run__steps_per_radian=20.0),
    "elastic fixed dt": _cfg(run__dt=2e-8),
    "blocks per sample": _cfg(run__sample_interval=2e-6),  # n_sub > 1: several blocks per sample
    "viscoelastic": _cfg(contact__law="viscoelastic", contact__A=1e-6),
    "dashpot": _cfg(contact__law="dashpot", contact__gamma=20.0),
    "precompressed": _cfg(chain__precompression=5.0),
    "misaligned": _cfg(chain__offsets_mm=[0.0, 0.5, 1.0, 0.2, 0.0, -0.3, 0.0, 0.1]),
    "free end": _cfg(wall__type="none"),
    "protected body": _cfg(wall__type="body", wall__mass=0.05, wall__stiffness=2e5, wall__damping=5.0,
                           contact__law="viscoelastic", contact__A=1e-6),
}


def _system(cfg: dict):
    c = parse_config(cfg)
    return build_model(c).system(), c


@pytest.mark.parametrize("name", list(CASES))
def test_taped_run_is_the_engine_run_bit_for_bit(name):
    system, cfg = _system(CASES[name])
    raw = run_verlet(system, cfg.run.duration, cfg.run.sample_interval, dt=cfg.run.dt,
                     steps_per_radian=cfg.run.steps_per_radian)
    tape = D.record(system, cfg.run.duration, cfg.run.sample_interval, dt=cfg.run.dt,
                    steps_per_radian=cfg.run.steps_per_radian, contacts=range(system.n_contacts))
    assert tape.n_steps == raw.n_steps
    assert np.array_equal(tape.forces, raw.contact_force)
    assert np.array_equal(tape.max_force, raw.max_force)
    assert (tape.peak_wall_force, tape.peak_wall_time) == (raw.peak_wall_force, raw.peak_wall_time)
    # the forces of sample k are those of step step_end[k] - 1, and the step of the peak is among them
    assert tape.step_end[-1] == tape.n_steps and np.all(np.diff(tape.step_end) >= 1)
    # the tangent model steps the same way (it takes its partials inside its own copy of the steps)
    _, forces, _, _ = D.tangents(system, {"kappa": np.zeros((1, system.kappa.size))}, cfg.run.duration,
                                 cfg.run.sample_interval, dt=cfg.run.dt, steps_per_radian=cfg.run.steps_per_radian,
                                 contacts=range(system.n_contacts))
    assert np.array_equal(forces, raw.contact_force)


def _all_directions(system, names):
    """One tangent direction per entry of each named System array (its unit vectors)."""
    dirs, labels = {}, []
    rows = sum(getattr(system, n).size for n in names)
    r = 0
    for n in names:
        size = getattr(system, n).size
        block = np.zeros((rows, size))
        block[r:r + size] = np.eye(size)
        dirs[n] = block
        labels += [(n, i) for i in range(size)]
        r += size
    return dirs, labels


@pytest.mark.parametrize("name", ["elastic adaptive", "viscoelastic", "dashpot", "precompressed", "misaligned",
                                  "protected body"])
def test_adjoint_equals_tangent_for_every_parameter(name):
    system, cfg = _system(CASES[name])
    args = (cfg.run.duration, cfg.run.sample_interval)
    kw = {"dt": cfg.run.dt, "steps_per_radian": cfg.run.steps_per_radian}
    tape = D.record(system, *args, **kw)
    wall = system.n_beads
    # a scalar reading the wall force at three samples and the striker contact at one step
    seeds = D.Seeds.build([(tape.sample_step(500), wall, 0.7), (tape.sample_step(1900), wall, -1.3),
                           (tape.sample_step(2600), wall, 2.0), (tape.sample_step(40) + 1, 0, 0.5)])
    grad = D.gradient(tape, seeds)
    names = ["kappa", "damping", "de", "dx0", "rsum", "inv_mass", "v0"]
    if name == "precompressed":  # d0 and f_ext are differentiated where the chain carries a static load
        names += ["d0", "fext"]
    dirs, labels = _all_directions(system, names)
    if system.body:  # the mount's spring and dashpot, one direction each
        for n in ("mount_k", "mount_c"):
            dirs = {k: np.concatenate([v, np.zeros((1, v.shape[1]))]) for k, v in dirs.items()}
            dirs[n] = np.zeros((len(labels) + 1, 1))
            dirs[n][-1, 0] = 1.0
            labels.append((n, 0))
    _, _, _, dj = D.tangents(system, dirs, *args, seeds=seeds, **kw)
    adj = np.array([grad[n][i] for n, i in labels])
    scale = np.abs(adj).max()
    assert scale > 0
    assert np.allclose(adj, dj, rtol=1e-9, atol=1e-11 * scale)


def test_checkpoint_spacing_does_not_change_the_gradient(monkeypatch):
    system, cfg = _system(CASES["viscoelastic"])
    args = (system, cfg.run.duration, cfg.run.sample_interval)
    tape = D.record(*args)
    seeds = D.Seeds.build([(tape.peak_step, system.n_beads, 1.0)])
    default = D.gradient(tape, seeds)
    monkeypatch.setattr(D, "GROUP_STEPS", 1)  # a checkpoint at every block
    fine = D.record(*args)
    assert fine.group == 1 < tape.group
    every = D.gradient(fine, seeds)
    for n in default:
        assert np.allclose(default[n], every[n], rtol=1e-12, atol=0.0), n


def test_tangent_of_the_trace_is_its_derivative():
    """d(wall force samples)/d(kappa_j) by the tangent model against central differences of the
    runs (fixed step: the same step sequence on both sides)."""
    system, cfg = _system(CASES["elastic fixed dt"])
    j = 4
    dirs = {"kappa": np.eye(system.kappa.size)[j][None, :]}
    _, f, ft, _ = D.tangents(system, dirs, cfg.run.duration, cfg.run.sample_interval, dt=cfg.run.dt)
    h = 1e-5 * system.kappa[j]
    runs = []
    for s in (1, -1):
        k = system.kappa.copy()
        k[j] += s * h
        runs.append(run_verlet(dataclasses.replace(system, kappa=k), cfg.run.duration, cfg.run.sample_interval,
                               dt=cfg.run.dt).contact_force[:, -1])
    fd = (runs[0] - runs[1]) / (2 * h)
    assert np.allclose(ft[0, :, 0], fd, rtol=1e-4, atol=1e-4 * np.abs(fd).max())
