"""The contact-law registry and the laws run by the generated engines (power, Hunt-Crossley, a user's).

Each engine is compared with the single run (the same generated loop), the power law at n = 3/2
with the elastic law (paper eq. 1), Hunt-Crossley's restitution with the closed form it is set
from, and every law's partials with central differences.
"""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.errors import ConfigError
from hertzchain.laws import get_law, law_names

ROOT = Path(__file__).resolve().parents[1]
USER_LAW = ROOT / "examples" / "laws" / "tsuji.py"


def _run(law, n=8, duration=2.5e-4, velocity=0.3, integrator="auto", **kw):
    model = hc.Model(hc.Chain.uniform(n, 10e-3), hc.Striker(8e-3, velocity), law=law, **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return hc.simulate(model, duration, integrator=integrator), model


def test_power_law_at_three_halves_is_the_elastic_law():
    """Contract: exponent 1.5 without stiffness takes the pair's Hertz constant: the elastic run to
    1e-12, on the Verlet (the generated loop, the same arithmetic) and with the defaults (auto's
    rkn4 runs the law as the elastic law it is: ``laws.hertz_equivalent``)."""
    for integrator in ("verlet", "auto"):
        a, _ = _run(hc.Elastic(), precompression=2.0, integrator=integrator)
        b, _ = _run(hc.PowerLaw(1.5), precompression=2.0, integrator=integrator)
        assert a.attrs["integrator_used"] == b.attrs["integrator_used"]
        for name in ("contact_force", "kinetic_energy", "potential_energy"):
            x, y = a[name].values, b[name].values
            assert np.max(np.abs(x - y)) <= 1e-12 * np.max(np.abs(x)), (integrator, name)


@pytest.mark.parametrize("law", [hc.PowerLaw(2.0, 2e9), hc.PowerLaw(1.0, 5e5)])
def test_power_law_conserves_energy_and_rebounds_elastically(law):
    """A power law is conservative: kinetic + stored energy k d^(n+1)/(n+1) constant to Verlet's
    accuracy, nothing dissipated; a two-body impact has e = 1."""
    ds, _ = _run(law)
    total = ds.kinetic_energy.values + ds.potential_energy.values
    assert np.ptp(total) < 1e-5 * total[0]
    assert float(ds.dissipated_energy[-1]) == 0.0
    assert hc.restitution(0.3, law, 8e-3, "AISI52100", 10e-3) == pytest.approx(1.0, abs=1e-6)


def test_power_law_peak_force_of_a_two_body_impact():
    """Striker on one free bead: at the peak all the kinetic energy of the relative motion is
    stored, k d_m^(n+1) / (n+1) = mu v^2 / 2, and F_max = k d_m^n (closed form)."""
    n, k, v = 2.0, 3e9, 0.2
    model = hc.Model(hc.Chain.uniform(1, 10e-3), hc.Striker(8e-3, v), hc.Wall("none"), law=hc.PowerLaw(n, k))
    system = model.system()
    mu = 1.0 / (system.inv_mass[0] + system.inv_mass[1])
    d_m = ((n + 1) * 0.5 * mu * v * v / k) ** (1 / (n + 1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = hc.simulate(model, 1e-3, hc.Probes(sample_interval=1e-7))
    assert float(ds.contact_force.isel(contact=0).max()) == pytest.approx(k * d_m**n, rel=1e-4)


@pytest.mark.parametrize("e, bound", [(0.5, 0.03), (0.9, 0.007), (0.99, 0.001)])
def test_hunt_crossley_restitution_at_any_speed(e, bound):
    """Flores et al.'s closed form gives e within the stated accuracy, the same at every speed (the
    law is scale-free)."""
    law = hc.HuntCrossley(e)
    got = [hc.restitution(v, law, 8e-3, "AISI52100", 26e-3) for v in (0.02, 0.3, 4.0)]
    assert max(abs(x - e) for x in got) <= bound
    assert np.ptp(got) < 1e-5


def test_hunt_crossley_balances_energy():
    """Kinetic + stored + dissipated energy stays the striker's initial energy."""
    ds, _ = _run(hc.HuntCrossley(0.7))
    total = ds.kinetic_energy.values + ds.potential_energy.values + ds.dissipated_energy.values
    assert np.ptp(total) < 1e-4 * total[0]
    assert float(ds.dissipated_energy[-1]) > 0.01 * total[0]


@pytest.mark.parametrize("name, p, s", [("elastic", 0.0, 0.0), ("viscoelastic", 4e-6, 0.0), ("dashpot", 30.0, 0.0),
                                        ("power", 2.3, 0.0), ("power", 1.5, 0.0), ("hunt_crossley", 0.2, 0.4)])
def test_partials_match_central_differences(name, p, s):
    spec = get_law(name)
    d, rate, k = 7e-6, 0.13, 8e9
    x = np.array([d, rate, k, p])
    analytic = spec.partials(d, rate, k, p, s)
    for i in range(4):
        h = 1e-6 * x[i] if x[i] else 1e-9
        up, dn = x.copy(), x.copy()
        up[i] += h
        dn[i] -= h
        fd = (spec.force(*up, s) - spec.force(*dn, s)) / (2 * h)
        assert analytic[i] == pytest.approx(fd, rel=1e-6, abs=1e-12 * abs(spec.force(d, rate, k, p, s)) / x[i]
                                            if x[i] else 1e-9)


@pytest.mark.slow  # compiles the batch loops of generated laws (~15 s each)
def test_batch_members_equal_their_single_runs():
    """simulate_batch runs each generated law's own loop: every member is its single run."""
    laws = [hc.PowerLaw(2.0, 2e9), hc.HuntCrossley(0.8), hc.Elastic()]
    models = [hc.Model(hc.Chain.uniform(6 + i, 10e-3), hc.Striker(8e-3, 0.3), law=law) for i, law in enumerate(laws)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        batch = hc.simulate_batch(models, duration=2e-4)
        for i, model in enumerate(models):
            single = hc.simulate(model, 2e-4, integrator="verlet").contact_force.values  # the batch engine's method
            member = batch.contact_force.isel(member=i).values[:, :single.shape[1]]
            assert np.max(np.abs(member - single)) <= 1e-12 * np.max(np.abs(single))


def test_config_takes_the_new_laws_and_names_bad_fields():
    base = {"chain": {"uniform": {"n": 5, "diameter_mm": 10}}, "striker": {"diameter_mm": 8, "velocity": 0.2},
            "run": {"duration": 2e-4}}
    model = hc.build_model(hc.parse_config({**base, "contact": {"law": "power", "exponent": 2.0, "stiffness": 1e9}}))
    assert model.law == hc.PowerLaw(2.0, 1e9)
    assert hc.build_model(hc.parse_config({**base, "contact": {"law": "hunt_crossley", "restitution": 0.8}})).law \
        == hc.HuntCrossley(0.8)
    for contact, field in [({"law": "power", "exponent": 1.0}, "stiffness"), ({"law": "power", "exponent": 0.5}, "exponent"),
                           ({"law": "hunt_crossley", "restitution": 0.0}, "restitution"),
                           ({"law": "power", "exponent": 2.0, "A": 1e-6}, "A"), ({"law": "no_such_law"}, "law")]:
        with pytest.raises(ConfigError, match="contact") as info:
            hc.parse_config({**base, "contact": contact})
        assert field in str(info.value)


def test_engines_without_the_generated_laws_refuse_naming_the_field():
    model = hc.Model(hc.Chain.uniform(5, 10e-3), hc.Striker(8e-3, 0.2), law=hc.PowerLaw(2.0, 1e9))
    elastic = hc.Model(hc.Chain.uniform(5, 10e-3), hc.Striker(8e-3, 0.2))
    with pytest.raises(ConfigError, match="contact.law"):  # the GPU runs one generated law per batch
        hc.simulate_batch([model, elastic], duration=1e-4, device="cuda")
    assert hc.simulate(model, 1e-4, integrator="rkn4").attrs["integrator_used"] == "rkn4"  # rkn4 takes it


def test_user_law_from_python_and_by_name_in_a_config():
    """A law registered from a user's file (Tsuji's damped Hertz) runs by name from a config; its
    energy balances and, as its scaling promises, its restitution does not depend on the speed."""
    import runpy

    ns = runpy.run_path(str(USER_LAW))
    assert "tsuji" in law_names()
    cfg = {"chain": {"uniform": {"n": 5, "diameter_mm": 10}}, "striker": {"diameter_mm": 8, "velocity": 0.2},
           "contact": {"law": "tsuji", "parameters": {"eta": 300.0}}}
    model = hc.build_model(hc.parse_config(cfg))
    assert model.law == ns["Tsuji"](300.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = hc.simulate(model, 2e-4)
    total = ds.kinetic_energy.values + ds.potential_energy.values + ds.dissipated_energy.values
    assert np.ptp(total) < 1e-4 * total[0] and float(ds.dissipated_energy[-1]) > 0.01 * total[0]
    e = [hc.restitution(v, model.law, 8e-3, "AISI52100", 10e-3) for v in (0.05, 0.5)]
    assert 0.5 < e[0] < 0.999 and e[1] == pytest.approx(e[0], abs=1e-5)
    with pytest.raises(ConfigError, match="eta"):
        hc.parse_config({**cfg, "contact": {"law": "tsuji", "parameters": {"eta": -1.0}}})


@pytest.mark.slow  # a fresh process compiles the user's law again (~18 s)
def test_cli_loads_a_law_file_only_when_named(tmp_path):
    toml = tmp_path / "c.toml"
    toml.write_text('[chain]\nuniform = {n = 4, diameter_mm = 10}\n[striker]\ndiameter_mm = 8\nvelocity = 0.2\n'
                    '[contact]\nlaw = "tsuji"\nparameters = {eta = 300.0}\n[run]\nduration = 1e-4\n')
    # a fresh process (this one may have registered the law already), running this checkout
    cmd = [sys.executable, "-c", "import sys; from hertzchain.cli.main import main; sys.exit(main(sys.argv[1:]))",
           "run", str(toml), "--out", str(tmp_path / "o.nc")]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(hc.__file__).parents[1]),
                                                        os.environ.get("PYTHONPATH", "")])}
    refused = subprocess.run(cmd, capture_output=True, text=True, env=env)
    assert refused.returncode == 2 and "contact.law" in refused.stderr + refused.stdout
    ran = subprocess.run(cmd + ["--laws", str(USER_LAW)], capture_output=True, text=True, env=env)
    assert ran.returncode == 0, ran.stderr
    assert (tmp_path / "o.nc").exists()


@pytest.mark.slow  # compiles the batch loops of generated laws (~15 s each)
def test_sweep_members_equal_their_single_runs(tmp_path):
    """A sweep over a generated law's own parameter: each member's metrics are its single run's on
    the same integrator (a batch steps registry laws with the Verlet; a single run's default,
    ``auto``, takes rkn4 for a stateless one)."""
    sweep = {"base": {"chain": {"uniform": {"n": 6, "diameter_mm": 10.0}},
                      "striker": {"diameter_mm": 8.0, "velocity": 0.2},
                      "contact": {"law": "power", "exponent": 2.0, "stiffness": 1e13},
                      "run": {"duration": 3e-4, "sample_interval": 1e-7}},
             "sweep": {"mode": "grid", "chunk_size": 2, "parameters": {"contact.exponent": [1.8, 2.2]}}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        metrics = hc.run_sweep(sweep, tmp_path / "s").metrics
        for n, peak in zip(metrics["contact.exponent"], metrics["peak_wall_force"]):
            model = hc.Model(hc.Chain.uniform(6, 10e-3), hc.Striker(8e-3, 0.2), law=hc.PowerLaw(n, 1e13))
            single = hc.simulate(model, 3e-4, hc.Probes(sample_interval=1e-7),
                                 integrator="verlet").attrs["peak_wall_force"]
            assert single > 1.0 and peak == pytest.approx(single, rel=1e-12)


@pytest.mark.slow  # a fresh process under the simulator compiles both laws (~20 s)
def test_cuda_kernel_from_the_law_matches_the_cpu_engine_in_the_simulator():
    """The CUDA kernel compiled from the laws' own Python source (cuda_generated.py), run by Numba's
    CUDA simulator, gives the CPU engine's forces (the simulator does the CPU's arithmetic, no FMA:
    bit for bit) and energies to rounding."""
    import json

    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1",
           "PYTHONPATH": os.pathsep.join([str(Path(hc.__file__).parents[1]), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, str(Path(__file__).with_name("cuda_laws.py"))], capture_output=True,
                          text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    for law, res in result.items():
        assert res["peak_force"] > 1.0, law
        assert res["force"] == 0.0 and res["energy"] < 1e-12, (law, res)
        assert res.get("body", 0.0) == 0.0, (law, res)  # a protected body's record
