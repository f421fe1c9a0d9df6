"""integrator = "auto" and threads = "auto" (hertzchain.engine_choice): the choice per model kind,
explicit values kept, the result's attributes, and the auto path within the documented accuracy of
a DOP853 reference on random small chains."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.config import parse_config
from hertzchain.engine_choice import AUTO_THREADS_MIN_BEADS, BEADS_PER_THREAD, choose_engine
from hertzchain.errors import ConfigError

STRIKER = hc.Striker(8e-3, 0.2)
ELASTIC = hc.Model(hc.Chain.uniform(6, 20e-3), STRIKER)
MODEL_KINDS = {  # model kind -> the integrator "auto" picks
    "aligned elastic": (ELASTIC, "rkn4"),
    "elastic, free end": (hc.Model(hc.Chain.uniform(6, 20e-3), STRIKER, hc.Wall("none")), "rkn4"),
    "precompressed elastic": (hc.Model(hc.Chain.uniform(6, 20e-3), STRIKER, precompression=1.0), "rkn4"),
    "elastic under gravity": (hc.Model(hc.Chain.uniform(6, 20e-3), STRIKER, gravity=9.81), "rkn4"),
    "power law": (hc.Model(hc.Chain.uniform(6, 20e-3), STRIKER, law=hc.PowerLaw(2.0, 2e9)), "rkn4"),
    "hunt_crossley": (hc.Model(hc.Chain.uniform(6, 20e-3), STRIKER, law=hc.HuntCrossley(0.8)), "verlet"),
    "dashpot": (hc.Model(hc.Chain.uniform(6, 20e-3), STRIKER, law=hc.Dashpot(gamma=20.0)), "rkn4"),
    "viscoelastic": (hc.Model(hc.Chain.uniform(6, 20e-3), STRIKER, law=hc.Viscoelastic(A=4e-6)), "rkn4"),
    "elastoplastic": (hc.Model(hc.Chain.uniform(6, 20e-3), STRIKER, law=hc.Elastoplastic()), "verlet"),
    "offset dashpot": (hc.Model(hc.Chain.uniform(6, 20e-3).with_offsets({3: 1e-4}), STRIKER,
                                law=hc.Dashpot(gamma=20.0)), "rkn4"),
    "dashpot, protected body": (hc.Model(hc.Chain.uniform(6, 20e-3), STRIKER, hc.Wall("body", mass=1.0, stiffness=1e6),
                                         law=hc.Dashpot(gamma=20.0)), "verlet"),
    "offset beads": (hc.Model(hc.Chain.uniform(6, 20e-3).with_offsets({3: 1e-4}), STRIKER), "rkn4"),
    "protected body": (hc.Model(hc.Chain.uniform(6, 20e-3), STRIKER, hc.Wall("body", mass=1.0, stiffness=1e6)),
                       "verlet"),
}


@pytest.mark.parametrize("kind", list(MODEL_KINDS))
def test_auto_integrator_per_model_kind(kind):
    model, expected = MODEL_KINDS[kind]
    choice = choose_engine(model.system(), cores=2, load=0.0)
    assert (choice.integrator, choice.threads) == (expected, 1)
    assert choice.reason.startswith(expected)


def test_auto_keeps_the_verlet_where_its_settings_are_given():
    s = ELASTIC.system()
    assert choose_engine(s, steps_per_radian=800.0, cores=2, load=0.0).integrator == "verlet"
    assert choose_engine(s, dt=1e-8, cores=2, load=0.0).integrator == "verlet"
    # several threads: rkn4 where its threads run the model (aligned elastic), else the Verlet
    assert choose_engine(s, threads=2, cores=2, load=0.0).integrator == "rkn4"
    dashpot = MODEL_KINDS["dashpot"][0].system()
    assert choose_engine(dashpot, threads=2, cores=2, load=0.0).integrator == "verlet"


def test_explicit_values_are_kept_and_checked():
    s = ELASTIC.system()
    for name in ("verlet", "rkn4", "dop853", "rk45"):
        assert choose_engine(s, name, 1).integrator == name
    dissipative = MODEL_KINDS["dashpot"][0].system()
    assert choose_engine(dissipative, "rkn4").integrator == "rkn4"
    with pytest.raises(ConfigError) as exc:
        choose_engine(MODEL_KINDS["dashpot, protected body"][0].system(), "rkn4")
    assert exc.value.field == "run.integrator" and "protected body" in exc.value.message
    assert choose_engine(dissipative, "verlet", 2).threads == 2  # the threaded engine runs every law
    with pytest.raises(ConfigError, match="run.threads") as exc:  # not a protected body
        choose_engine(MODEL_KINDS["dashpot, protected body"][0].system(), "verlet", 2)
    assert "wall.type" in exc.value.message
    with pytest.raises(ConfigError, match="run.integrator"):
        choose_engine(s, "euler")
    for bad in (0, True, 2.0, "two"):
        with pytest.raises(ConfigError, match="run.threads"):
            choose_engine(s, "verlet", bad)


def test_auto_threads_only_for_long_chains_with_free_cores():
    long_chain = hc.Model(hc.Chain.uniform(4 * BEADS_PER_THREAD, 5e-3), STRIKER).system()
    short = hc.Model(hc.Chain.uniform(AUTO_THREADS_MIN_BEADS - 1, 5e-3), STRIKER).system()
    # the Verlet on a long aligned elastic chain: the free cores (the load beyond this process's own)
    assert choose_engine(long_chain, "verlet", cores=8, load=1.0).threads == 4  # beads per thread bound it
    assert choose_engine(long_chain, "verlet", cores=2, load=1.0).threads == 2
    assert choose_engine(long_chain, "verlet", cores=2, load=0.0).threads == 2
    assert choose_engine(long_chain, "verlet", cores=4, load=3.0).threads == 2
    # shared cores: one thread (a barrier waiting for a scheduler slice is slower than one thread)
    assert choose_engine(long_chain, "verlet", cores=2, load=2.2).threads == 1
    assert choose_engine(long_chain, "verlet", cores=1, load=0.0).threads == 1
    # too short, not the Verlet, or a model the threaded engine does not run: one thread
    assert choose_engine(short, "verlet", cores=16, load=0.0).threads == 1
    # auto picks rkn4, whose threads run aligned elastic chains (hertzchain.integrate.drivers.rkn_threaded)
    auto = choose_engine(long_chain, cores=16, load=0.0)
    assert (auto.integrator, auto.threads) == ("rkn4", 4)
    # every contact law and offsets: the Verlet's threaded engine runs them (auto picks rkn4, on
    # one thread, for the hand-written laws but the elastic-plastic one)
    chain = hc.Chain.uniform(4 * BEADS_PER_THREAD, 5e-3)
    for law in (hc.Dashpot(gamma=1.0), hc.Viscoelastic(A=1e-6), hc.Elastoplastic(), hc.PowerLaw(1.7, 1e9),
                hc.HuntCrossley(0.8)):
        diss = hc.Model(chain, STRIKER, law=law).system()
        assert choose_engine(diss, "verlet", cores=16, load=0.0).threads == 4
        assert choose_engine(diss, "verlet", cores=2, load=2.2).threads == 1  # shared cores
        auto = choose_engine(diss, cores=16, load=0.0)
        assert auto.threads == (4 if auto.integrator == "verlet" else 1)
    # registry laws: rkn4 without per-contact state, the Verlet (rkn4 on request) with it
    for law, engine in ((hc.PowerLaw(1.7, 1e9), ("rkn4", 1)), (hc.HuntCrossley(0.8), ("verlet", 4))):
        auto = choose_engine(hc.Model(chain, STRIKER, law=law).system(), cores=16, load=0.0)
        assert (auto.integrator, auto.threads) == engine
    # the elastic-plastic chain: the Verlet (rkn4 on request), threads where cores are free
    assert choose_engine(hc.Model(chain, STRIKER, law=hc.Elastoplastic()).system(), cores=16, load=0.0).threads == 4
    offsets = hc.Model(chain.with_offsets({3: 1e-5}), STRIKER).system()
    assert choose_engine(offsets, "verlet", cores=2, load=0.0).threads == 2
    body = hc.Model(chain, STRIKER, hc.Wall("body", mass=1.0, stiffness=1e6)).system()
    assert choose_engine(body, cores=16, load=0.0).threads == 1
    # explicit threads kept
    assert choose_engine(short, "verlet", 3).threads == 3


def test_config_defaults_are_auto_and_checked():
    cfg = parse_config({"chain": {"diameters_mm": [20.0] * 3}})
    assert cfg.run.integrator == "auto" and cfg.run.threads == "auto" and cfg.run.verlet_steps_per_radian is None
    spr = parse_config({"chain": {"diameters_mm": [20.0] * 3}, "run": {"steps_per_radian": 400.0}}).run
    assert spr.verlet_steps_per_radian == 400.0  # set, even to the default: the Verlet's accuracy asked for
    assert parse_config({"chain": {"diameters_mm": [20.0] * 3}, "run": {"threads": 2}}).run.threads == 2
    for bad in (0, 2.5, "many", True):
        with pytest.raises(ConfigError) as exc:
            parse_config({"chain": {"diameters_mm": [20.0] * 3}, "run": {"threads": bad}})
        assert exc.value.field == "run.threads"


def test_result_records_the_choice():
    ds = hc.simulate(ELASTIC, 4e-4, hc.Probes(sample_interval=1e-6))
    assert (ds.attrs["integrator_used"], ds.attrs["threads_used"]) == ("rkn4", 1)
    assert ds.attrs["integrator"] == "rkn4" and "aligned elastic" in ds.attrs["engine_choice"]
    ds = hc.simulate(MODEL_KINDS["dashpot"][0], 4e-4, hc.Probes(sample_interval=1e-6))
    assert (ds.attrs["integrator_used"], ds.attrs["threads_used"]) == ("rkn4", 1)
    assert "aligned dissipative" in ds.attrs["engine_choice"]
    ds = hc.simulate(MODEL_KINDS["dashpot, protected body"][0], 4e-4, hc.Probes(sample_interval=1e-6))
    assert ds.attrs["integrator_used"] == "verlet" and "protected body" in ds.attrs["engine_choice"]
    ds = hc.simulate(ELASTIC, 4e-4, hc.Probes(sample_interval=1e-6), integrator="verlet")
    assert ds.attrs["integrator_used"] == "verlet" and "asked for" in ds.attrs["engine_choice"]


def _random_chain(rng) -> hc.Chain:
    return hc.Chain.from_diameters(rng.uniform(10e-3, 26e-3, size=int(rng.integers(3, 8))))


# Documented accuracy of the defaults (docs/guide/running.rst): the peak wall force within 1e-6 of
# DOP853 on elastic chains (rkn4: ~1e-8) and on dissipative laws (rkn4 for Kuwabara-Kono and the
# dashpot, whose step lands on every contact's closing, clip and reload: ~4e-7 on chain 1).
@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("law, rel", [(None, 1e-6), (hc.Dashpot(gamma=15.0), 1e-6), (hc.Viscoelastic(A=2e-6), 1e-6)])
def test_auto_within_documented_accuracy_of_dop853(seed, law, rel):
    rng = np.random.default_rng(seed)
    model = hc.Model(_random_chain(rng), hc.Striker(float(rng.uniform(6e-3, 12e-3)), float(rng.uniform(0.1, 0.3))),
                     law=law or hc.Elastic())
    probes = hc.Probes(sample_interval=1e-6, contacts=())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", hc.ElasticLimitWarning)
        auto = hc.simulate(model, "auto", probes)
        ref = hc.simulate(model, "auto", probes, integrator="dop853", rtol=1e-12)
    assert auto.attrs["integrator_used"] == "rkn4"
    f, fr = auto.attrs["peak_wall_force"], ref.attrs["peak_wall_force"]
    assert fr > 1.0
    assert abs(f / fr - 1) < rel


def test_cli_verbose_names_the_engine(tmp_path, capsys):
    from hertzchain.cli.main import main

    cfg = tmp_path / "c.toml"
    cfg.write_text('[chain]\ndiameters_mm = [20.0, 20.0, 20.0]\n[striker]\ndiameter_mm = 8.0\nvelocity = 0.2\n'
                   '[run]\nduration = 2e-4\nsample_interval = 1e-6\n')
    assert main(["run", str(cfg), "--out", str(tmp_path / "r.nc"), "--verbose"]) == 0
    assert "engine: rkn4: aligned elastic chain; 1 thread(s)" in " ".join(capsys.readouterr().out.split())
    assert main(["run", str(cfg), "--out", str(tmp_path / "r.nc"), "--set", "contact.law=dashpot",
                 "--set", "contact.gamma=10.0", "--verbose"]) == 0
    assert "engine: rkn4: aligned dissipative chain; 1 thread(s)" in " ".join(capsys.readouterr().out.split())
    assert main(["run", str(cfg), "--out", str(tmp_path / "r.nc"), "--set", "contact.law=hunt_crossley",
                 "--set", "contact.restitution=0.8", "--set", "run.integrator=dop853"]) == 2
    assert "run.integrator" in capsys.readouterr().err
