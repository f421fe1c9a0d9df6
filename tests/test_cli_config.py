"""The config contract and the command line: outputs, and bad input giving exit status 2."""

from __future__ import annotations

import copy
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.cli.main import main
from hertzchain.config import parse_config, run_config

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture(scope="module")
def contract_cfg() -> dict:
    return tomllib.loads((EXAMPLES / "contract.toml").read_text())


def test_contract_config_writes_the_promised_netcdf(tmp_path, capsys):
    out = tmp_path / "result.nc"
    assert main(["run", str(EXAMPLES / "contract.toml"), "--out", str(out)]) == 0
    ds = hc.load(out)
    n = 19
    assert list(ds.contact.values) == list(range(n + 1))
    assert ds.time.attrs["units"] == "s"
    assert ds.contact_force.dims == ("time", "contact")
    assert ds.wall_force.dims == ("time",)
    assert ds.sensor_force.dims == ("time", "sensor") and list(ds.sensor.values) == [8, 12]
    assert {"kinetic_energy", "potential_energy"} <= set(ds.data_vars)
    assert ds.time.size == 25001 and ds.time.values[1] == pytest.approx(1e-7)
    # Striker 8 mm at 0.5 m/s on 26 mm beads passes the striker contact's elastic limit: a
    # warning on stderr and a record in the result.
    assert "elastic limit" in capsys.readouterr().err
    assert ds.attrs["elastic_limit_exceeded"] == 1
    cfg = json.loads(ds.attrs["config"])
    assert cfg["striker"]["velocity"] == 0.5 and cfg["chain"]["diameters_mm"][16] == 24


def _dump(data: dict) -> str:
    """Minimal TOML writer for the nested dicts of a run config (tests only)."""
    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, float) and v != v:
            return "nan"
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    lines = []
    for section, table in data.items():
        if not isinstance(table, dict):
            lines.append(f"{section} = {value(table)}")
            continue
        lines.append(f"[{section}]")
        lines += [f"{k} = {value(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


BAD_INPUTS = [
    (lambda d: d["chain"].update(diametres_mm=[1.0]), "chain.diametres_mm", "unknown key"),
    (lambda d: d["chain"]["diameters_mm"].__setitem__(3, -26.0), "chain.diameters_mm", "bead 4"),
    (lambda d: d["chain"]["diameters_mm"].__setitem__(3, 0.0), "chain.diameters_mm", "positive"),
    (lambda d: d["chain"]["diameters_mm"].__setitem__(5, float("nan")), "chain.diameters_mm[5]", "finite"),
    (lambda d: d["chain"].update(material="unobtainium"), "chain.material", "unknown material"),
    (lambda d: d["run"].update(duration=-2.5e-3), "run.duration", "greater than 0"),
    (lambda d: d["run"].update(dt=1e-5, sample_interval=1e-5), "run.dt", "too large"),
    (lambda d: d["striker"].update(velocity=0.0), "striker.velocity", "at least 1e-06"),
    (lambda d: d["wall"].update(type="sponge"), "wall.type", "flat"),
    (lambda d: d["probes"].update(sensors=[40]), "probes.sensors[0]", "does not exist"),
]


@pytest.mark.parametrize("mutate,field,words", BAD_INPUTS)
def test_bad_input_exit_2_naming_the_field(tmp_path, capsys, contract_cfg, mutate, field, words):
    data = copy.deepcopy(contract_cfg)
    mutate(data)
    path = tmp_path / "bad.toml"
    path.write_text(_dump(data))
    assert main(["run", str(path), "--out", str(tmp_path / "x.nc")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and field in err and words in err
    assert "Traceback" not in err
    assert not (tmp_path / "x.nc").exists()


def test_bad_toml_and_missing_file(tmp_path, capsys):
    path = tmp_path / "broken.toml"
    path.write_text("[chain\ndiameters_mm = [1")
    assert main(["run", str(path), "--out", str(tmp_path / "x.nc")]) == 2
    assert "not valid TOML" in capsys.readouterr().err
    assert main(["run", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "x.nc")]) == 2
    assert main(["plot", str(tmp_path / "nope.nc"), "--out", str(tmp_path / "x.png")]) == 2


def test_usage_error_is_exit_2(capsys):
    assert main(["run"]) == 2
    assert main(["frobnicate"]) == 2


def test_plot_and_analyze_commands(tmp_path, capsys):
    out = tmp_path / "c1.nc"
    assert main(["run", str(EXAMPLES / "chain1.toml"), "--out", str(out), "-q"]) == 0
    png = tmp_path / "c1.png"
    assert main(["plot", str(out), "--out", str(png)]) == 0
    assert png.stat().st_size > 10_000
    capsys.readouterr()
    assert main(["analyze", str(out), "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    wall = next(r for r in rows if r["signal"] == "wall_force")
    ds = hc.load(out)
    # The cos^6 fit of the loading part (paper Sec. III) lands near the sampled maximum; the
    # pulse that left the taper is asymmetric, so the extrapolated F_m sits ~0.7 % above it.
    assert wall["peak_force"] == pytest.approx(ds.wall_force.max().item(), rel=1e-2)
    assert wall["time_of_flight"] == pytest.approx(ds.attrs["peak_wall_time"], abs=0.1 * wall["duration"])
    assert wall["front_momentum"] + wall["tail_momentum"] == pytest.approx(
        np.trapezoid(ds.wall_force.values, ds.time.values), rel=1e-9)


def test_config_builders_match_python_api():
    cfg = parse_config({"chain": {"uniform": {"n": 16, "diameter_mm": 26}, "taper": {"n": 14, "q": 0.056},
                                  "substitutions": [{"bead": 18, "diameter_mm": 22.0}],
                                  "offsets_fraction": [0.0] * 21 + [0.05] + [0.0] * 8}})
    from hertzchain.config import build_chain

    chain = build_chain(cfg)
    expected = hc.Chain.uniform(16, 26e-3).append_taper(14, 0.056).substitute(18, diameter=22e-3)
    np.testing.assert_allclose(chain.diameters, expected.diameters)
    assert chain.offsets[21] == pytest.approx(0.05 * chain.diameters[21])


def test_config_section_errors():
    with pytest.raises(hc.ConfigError, match="exactly one of diameters_mm, preset or uniform"):
        parse_config({"chain": {"preset": "chain1", "diameters_mm": [26.0]}})
    with pytest.raises(hc.ConfigError, match="law 'viscoelastic' needs exactly one of A or eps"):
        parse_config({"chain": {"preset": "chain1"}, "contact": {"law": "viscoelastic"}})
    with pytest.raises(hc.ConfigError, match=r"^chain\.truncate"):
        from hertzchain.config import build_chain

        build_chain(parse_config({"chain": {"preset": "chain2", "truncate": 40}}))


def test_instrument_section_adds_measured_signals():
    cfg = tomllib.loads((EXAMPLES / "chain1_measured.toml").read_text())
    cfg["run"]["duration"] = 2.8e-3  # the 0.4 ms scope record after the trigger fits inside the run
    ds = run_config(cfg)
    ideal = ds.wall_force.max().item()
    measured = ds.measured_wall_force
    step = 2.0 / 2**8 / 0.1124  # full scale / levels / sensitivity: the 8-bit step in N
    # Averaging nine 8-bit acquisitions with noise keeps the peak within about one level.
    assert measured.max().item() == pytest.approx(ideal, abs=step)
    assert ds.measured_sensor_force.dims == ("sensor_scope_time", "sensor")
    assert "wall_force" in ds  # the ideal signal stays
    bad = copy.deepcopy(cfg)
    bad["instrument"]["wall"]["bits"] = 0
    with pytest.raises(hc.ConfigError, match=r"instrument\.wall\.bits"):
        run_config(bad)


def test_cli_package_layout_and_light_help():
    """hertzchain.cli: main registers every subcommand module, a subcommand imports only
    cli.common and the library (never another subcommand or main), and loading the whole command
    line, as ``hertzchain --help`` does, imports nothing heavy (the commands defer it)."""
    import ast
    import subprocess
    import sys

    from hertzchain.cli.main import cli

    folder = Path(hc.__file__).parent / "cli"
    subcommands = {p.stem for p in folder.glob("*.py")} - {"__init__", "__main__", "main", "common"}
    assert set(cli.commands) == subcommands
    for name in subcommands:
        for node in ast.walk(ast.parse((folder / f"{name}.py").read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 1:
                assert node.module == "common", f"cli/{name}.py imports .{node.module}"
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                assert not node.module.startswith("hertzchain.cli"), f"cli/{name}.py imports {node.module}"
    code = ("import sys, hertzchain.cli.main; print(sorted(m for m in ('numpy', 'xarray', 'matplotlib', 'rich', "
            "'scipy', 'numba', 'pandas') if m in sys.modules))")
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True).stdout.strip() == "[]"
