"""Property-based tests (Hypothesis): configs and files generated from the schema, then mutated
(types, magnitudes, encodings, truncation). Every outcome is either exit 0 with a finite result,
or exit 2 with a one-paragraph message naming a field of the input (or the file) that leaves
nothing behind; never a traceback, an internal error, a signal or a hang (issue 10, part 6).

The default suite runs a bounded number of examples; ``-m slow`` runs a longer campaign.
"""

from __future__ import annotations

import copy
import json
import math
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import hertzchain as hc
from hertzchain import checks
from hertzchain.cli.main import main

SECTIONS = {"chain", "striker", "wall", "contact", "run", "probes", "instrument", "materials"}
#: Runs projected past this [s] are refused in these tests (their estimate is what is tested; the
#: suite must not hang on a valid but long run a mutation made).
BUDGET_S = 3.0

HOSTILE = st.sampled_from([True, False, "0.5", "x", "", 0, -1, 1, 2**62, 1e300, -1e300, 1e-300, 0.0, -0.0,
                           float("nan"), float("inf"), -float("inf"), [], {}, [1.0, "a"], {"a": 1}, 10**30 // 10**12])


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, float):
        return "nan" if v != v else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    return repr(v)


def to_toml(data: dict) -> str:
    lines = []
    for key, value in data.items():
        if isinstance(value, dict):
            lines.append(f"[{json.dumps(key)}]")
            lines += [f"{json.dumps(k)} = {toml_value(x)}" for k, x in value.items()]
        else:
            lines.insert(0, f"{json.dumps(key)} = {toml_value(value)}")
    return "\n".join(lines) + "\n"


@st.composite
def valid_configs(draw) -> dict:
    """Small valid run configs over the schema's sections (each runs in well under a second)."""
    n = draw(st.integers(1, 6))
    chain: dict = draw(st.sampled_from(["uniform", "diameters"])) == "uniform" and \
        {"uniform": {"n": n, "diameter_mm": draw(st.floats(5.0, 30.0))}} or \
        {"diameters_mm": draw(st.lists(st.floats(5.0, 30.0), min_size=n, max_size=n))}
    if draw(st.booleans()):
        chain["taper"] = {"n": draw(st.integers(1, 4)), "q": draw(st.floats(0.0, 0.1))}
        n += chain["taper"]["n"]
    if draw(st.booleans()):
        chain["offsets_fraction"] = draw(st.lists(st.floats(-0.05, 0.05), min_size=n, max_size=n))
    law = draw(st.sampled_from(["elastic", "dashpot", "viscoelastic"]))
    contact = {"law": law}
    if law == "dashpot":
        contact["gamma"] = draw(st.floats(0.0, 1e3))
    elif law == "viscoelastic":
        contact["A"] = draw(st.floats(0.0, 1e-6))
    return {"chain": chain,
            "striker": {"diameter_mm": draw(st.floats(4.0, 12.0)), "velocity": draw(st.floats(0.01, 0.5))},
            "wall": {"type": draw(st.sampled_from(["flat", "none"]))},
            "contact": contact,
            "run": {"duration": draw(st.floats(2e-5, 2e-4)), "sample_interval": draw(st.sampled_from([1e-6, 2e-6]))},
            "probes": {"sensors": draw(st.lists(st.integers(1, n), max_size=2, unique=True))}}


def leaves(data, prefix=()):
    for k, v in data.items():
        if isinstance(v, dict) and v:
            yield from leaves(v, prefix + (k,))
        else:
            yield prefix + (k,)


@st.composite
def mutated_configs(draw) -> tuple[dict, str]:
    """A valid config with 0..3 mutations: a hostile value at a leaf, a key removed, a key added."""
    data = draw(valid_configs())
    for _ in range(draw(st.integers(0, 3))):
        paths = list(leaves(data))
        path = draw(st.sampled_from(paths))
        node = data
        for k in path[:-1]:
            node = node[k]
        action = draw(st.sampled_from(["value", "value", "scale", "delete", "add"]))
        if action == "value":
            node[path[-1]] = copy.deepcopy(draw(HOSTILE))  # sampled_from hands out the same object
        elif action == "scale" and isinstance(node[path[-1]], (int, float)) and not isinstance(node[path[-1]], bool):
            node[path[-1]] = node[path[-1]] * draw(st.sampled_from([-1, 0, 1e-30, 1e3, 1e30]))
        elif action == "delete":
            del node[path[-1]]
        else:
            node[draw(st.sampled_from(["extra", "diameter", "Velocity"]))] = copy.deepcopy(draw(HOSTILE))
    return data, to_toml(data)


@pytest.fixture
def run_budget(monkeypatch):
    real = checks.check_resources

    def within_budget(est, **kw):
        real(est, **kw)
        if est.seconds > BUDGET_S:
            raise hc.ConfigError("run.duration", f"projected {est.seconds:.3g} s, beyond this test's budget")

    monkeypatch.setattr(checks, "check_resources", within_budget)


def assert_clean_outcome(code: int, err: str, folder: Path, inputs: set[str], out: Path, data_keys: set[str]):
    assert "Traceback" not in err and "internal error" not in err, err
    assert code in (0, 2), err
    if code == 0:
        ds = hc.load(out)
        assert np.all(np.isfinite(ds.contact_force.values)) and np.all(np.isfinite(ds.kinetic_energy.values))
        assert {p.name for p in folder.iterdir()} == inputs | {out.name}
        return
    lines = [ln for ln in err.splitlines() if ln.startswith("error: ")]
    assert len(lines) == 1 and "\n\n" not in err.strip(), err
    field = lines[0][len("error: "):].split(": ", 1)[0]
    assert (field.split(".")[0].split("[")[0] in SECTIONS | data_keys or field.startswith(str(folder))
            or field.startswith("--")), err
    assert {p.name for p in folder.iterdir()} == inputs, "a refused run left files behind"


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                 HealthCheck.too_slow])
@given(case=mutated_configs())
def test_mutated_run_configs_exit_0_or_2(case, run_budget, capsys):
    _run_case(case, capsys)


@pytest.mark.slow
@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(case=mutated_configs())
def test_mutated_run_configs_campaign(case, run_budget, capsys):
    _run_case(case, capsys)


def _run_case(case, capsys) -> None:
    data, text = case
    folder = Path(tempfile.mkdtemp(prefix="hc-prop-"))
    try:
        cfg = folder / "c.toml"
        cfg.write_text(text)
        out = folder / "r.nc"
        code = main(["run", str(cfg), "--out", str(out), "-q"])
        err = capsys.readouterr().err
        event(f"exit {code}")  # --hypothesis-show-statistics: both outcomes are exercised
        assert_clean_outcome(code, err, folder, {"c.toml"}, out, set(data))
    finally:
        shutil.rmtree(folder)


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=valid_configs(), cut=st.floats(0.0, 1.0), encoding=st.sampled_from(["truncate", "latin-1", "bytes"]),
       junk=st.binary(min_size=1, max_size=8))
def test_damaged_config_files_exit_2_naming_the_file_or_field(case, cut, encoding, junk, run_budget, capsys):
    text = to_toml(case)
    raw = text.encode()
    if encoding == "truncate":
        raw = raw[: int(cut * len(raw))]
    elif encoding == "latin-1":
        raw = ("# \xe9t\xe9\n" + text).encode("latin-1")
    else:
        k = int(cut * len(raw))
        raw = raw[:k] + junk + raw[k:]
    folder = Path(tempfile.mkdtemp(prefix="hc-prop-"))
    try:
        (folder / "c.toml").write_bytes(raw)
        out = folder / "r.nc"
        code = main(["run", str(folder / "c.toml"), "--out", str(out), "-q"])
        err = capsys.readouterr().err
        assert_clean_outcome(code, err, folder, {"c.toml"}, out, set(case))
    finally:
        shutil.rmtree(folder)


@pytest.fixture(scope="module")
def result_bytes(tmp_path_factory) -> bytes:
    folder = tmp_path_factory.mktemp("result")
    cfg = folder / "c.toml"
    cfg.write_text('[chain]\nuniform = {n = 4, diameter_mm = 26.0}\n[striker]\nvelocity = 0.2\n'
                   '[run]\nduration = 4e-4\nsample_interval = 1e-6\n[probes]\nsensors = [2]\n')
    assert main(["run", str(cfg), "--out", str(folder / "r.nc"), "-q"]) == 0
    return (folder / "r.nc").read_bytes()


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(where=st.floats(0.0, 1.0), junk=st.binary(min_size=1, max_size=64), truncate=st.booleans(),
       command=st.sampled_from(["analyze", "plot"]))
def test_damaged_result_files_exit_0_or_2(result_bytes, where, junk, truncate, command, capsys):
    k = int(where * len(result_bytes))
    raw = result_bytes[:k] if truncate else result_bytes[:k] + junk + result_bytes[k + len(junk):]
    folder = Path(tempfile.mkdtemp(prefix="hc-prop-"))
    try:
        (folder / "r.nc").write_bytes(raw)
        argv = ["analyze", str(folder / "r.nc"), "--json"] if command == "analyze" else \
            ["plot", str(folder / "r.nc"), "--out", str(folder / "p.png")]
        code = main(argv)
        captured = capsys.readouterr()
        assert "Traceback" not in captured.err and "internal error" not in captured.err, captured.err
        assert code in (0, 2), captured.err
        if code == 2:
            assert captured.err.startswith(f"error: {folder / 'r.nc'}") or captured.err.startswith("error: --"), \
                captured.err
            assert sorted(p.name for p in folder.iterdir()) == ["r.nc"]
        elif command == "analyze":
            json.loads(captured.out, parse_constant=lambda c: pytest.fail(f"bare {c}"))
    finally:
        shutil.rmtree(folder)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rows=st.lists(st.tuples(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=3)),
                               st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=3))),
                     max_size=30),
       header=st.sampled_from(["time,force", "t_ms,F [N]", "a,b", "", "time;force"]))
def test_generated_csv_files_exit_0_or_2(rows, header, capsys):
    folder = Path(tempfile.mkdtemp(prefix="hc-prop-"))
    try:
        csv = folder / "s.csv"
        csv.write_text(header + "\n" + "".join(f"{a},{b}\n" for a, b in rows))
        code = main(["analyze", str(csv), "--json"])
        captured = capsys.readouterr()
        assert "Traceback" not in captured.err and "internal error" not in captured.err, captured.err
        assert code in (0, 2), captured.err
        if code == 2:
            assert captured.err.startswith(f"error: {csv}"), captured.err
        else:
            json.loads(captured.out, parse_constant=lambda c: pytest.fail(f"bare {c}"))
    finally:
        shutil.rmtree(folder)


@st.composite
def mutated_sweeps(draw) -> tuple[dict, str]:
    """A small valid sweep file, then 0..2 hostile values in its [sweep] table or its base."""
    sweep = {"parameters": {"striker.velocity": [0.1, 0.2]}, "chunk_size": 1}
    base = {"chain": {"uniform": {"n": 3, "diameter_mm": 26.0}},
            "run": {"duration": 2e-4, "sample_interval": 2e-6}}
    data = {"base": base, "sweep": sweep}
    for _ in range(draw(st.integers(0, 2))):
        target = draw(st.sampled_from(["chunk_size", "mode", "n", "seed", "store", "velocities", "parameter",
                                       "duration", "n_beads"]))
        value = draw(HOSTILE)
        if target == "velocities":
            sweep["parameters"]["striker.velocity"] = draw(st.lists(HOSTILE, min_size=1, max_size=2))
        elif target == "parameter":
            sweep["parameters"][draw(st.sampled_from(["run.duration", "chain.nope", "striker..x", "chain.taper.q"]))] = \
                draw(st.one_of(HOSTILE, st.lists(HOSTILE, min_size=1, max_size=2)))
        elif target == "duration":
            base["run"]["duration"] = value
        elif target == "n_beads":
            base["chain"]["uniform"]["n"] = value
        else:
            sweep[target] = value
    lines = ["[base.chain]", f"uniform = {toml_value(base['chain']['uniform'])}", "[base.run]"]
    lines += [f"{k} = {toml_value(v)}" for k, v in base["run"].items()]
    lines += ["[sweep]"] + [f"{json.dumps(k)} = {toml_value(v)}" for k, v in sweep.items()]
    return data, "\n".join(lines) + "\n"


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                 HealthCheck.too_slow])
@given(case=mutated_sweeps())
def test_mutated_sweep_files_exit_0_or_2_and_write_nothing_when_refused(case, run_budget, capsys):
    _, text = case
    folder = Path(tempfile.mkdtemp(prefix="hc-prop-"))
    try:
        (folder / "s.toml").write_text(text)
        out = folder / "out"
        code = main(["sweep", str(folder / "s.toml"), "--out", str(out), "-q"])
        err = capsys.readouterr().err
        event(f"exit {code}")
        assert "Traceback" not in err and "internal error" not in err, err
        assert code in (0, 2), err
        if code == 0:
            import pandas as pd

            df = pd.read_csv(out / "metrics.csv")
            assert len(df) >= 1 and np.all(np.isfinite(df["peak_wall_force"]))
        else:
            assert err.startswith("error: ") and len(err.strip().splitlines()) == 1, err
            field = err[len("error: "):].split(": ", 1)[0]
            assert field.split(".")[0].split("[")[0] in {"base", "sweep"} or field.startswith(str(folder)), err
            assert not out.exists(), "a refused sweep wrote files"
    finally:
        shutil.rmtree(folder)


# ------------------------------------------------------------------------- configs from the schema
def _bounds(metadata) -> tuple[float, float]:
    """(low, high) of a field from its annotated_types constraints (Ge, Gt, Le, Lt), also when they
    sit in a Field(...) of an Annotated type."""
    lo, hi = -1e6, 1e6
    for item in metadata:
        for m in getattr(item, "metadata", None) or [item]:
            for attr in ("ge", "gt"):
                if getattr(m, attr, None) is not None:
                    lo = getattr(m, attr)
            for attr in ("le", "lt"):
                if getattr(m, attr, None) is not None:
                    hi = getattr(m, attr)
    return lo, hi


def from_schema(annotation, metadata=(), depth: int = 0):
    """A strategy for values of a pydantic field: mostly inside its type and bounds, sometimes not."""
    import typing

    from pydantic import BaseModel

    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is typing.Annotated:
        return from_schema(args[0], list(metadata) + list(args[1:]), depth)
    if origin in (typing.Union, __import__("types").UnionType):
        return st.one_of(*(from_schema(a, metadata, depth) for a in args))
    if annotation is type(None):
        return st.none()
    if origin is typing.Literal:
        return st.sampled_from(args)
    if origin is list:
        return st.lists(from_schema(args[0], (), depth + 1), max_size=4)
    if origin is dict:
        return st.dictionaries(st.sampled_from(["steel", "soft"]), from_schema(args[1], (), depth + 1), max_size=1)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        if depth > 3:
            return st.just({})
        fields = annotation.model_fields
        return st.fixed_dictionaries(
            {k: from_schema(f.annotation, f.metadata, depth + 1) for k, f in fields.items() if f.is_required()},
            optional={k: from_schema(f.annotation, f.metadata, depth + 1) for k, f in fields.items()
                      if not f.is_required()})
    lo, hi = _bounds(metadata)
    if annotation is bool:
        return st.booleans()
    if annotation is int:  # small counts keep the test fast; huge ones come from HOSTILE
        inside = st.integers(int(max(lo, -1000)), int(max(min(hi, 1000), lo)))
        return st.one_of(*[inside] * 6, HOSTILE)
    if annotation is float:
        inside = st.floats(max(lo, -1e6), min(hi, 1e6), allow_nan=False) if lo <= hi else st.floats()
        return st.one_of(*[inside] * 6, HOSTILE)
    if annotation is str:
        return st.sampled_from(["AISI52100", "glass", "PTFE", "steel", "unobtainium", ""])
    return HOSTILE


@st.composite
def schema_configs(draw) -> dict:
    """A config drawn field by field from RunConfig; the chain keeps one source of beads (the
    cross-field rule) most of the time, so that many configs get past the schema to the model."""
    from hertzchain.config import RunConfig

    data = draw(from_schema(RunConfig))
    chain = data.get("chain")
    if isinstance(chain, dict) and draw(st.integers(0, 4)):
        sources = [k for k in ("diameters_mm", "preset", "uniform") if k in chain]
        for k in sources[1:]:
            del chain[k]
        if not sources:
            chain["uniform"] = {"n": draw(st.integers(1, 30)), "diameter_mm": draw(st.floats(1.0, 40.0))}
    return data


@settings(max_examples=60, deadline=None)
@given(data=schema_configs())
def test_configs_drawn_from_the_schema_are_accepted_or_refused_by_field(data):
    """Every field of the schema, inside and outside its type and bounds: parse_config, the model
    and the resource estimate either succeed or raise a ConfigError naming a field of the input
    (the chain or instrument key as written); never another exception."""
    from hertzchain.config import build_instruments, build_model, build_probes, parse_config
    from hertzchain.runs.simulation import auto_duration

    try:
        cfg = parse_config(data)
        model = build_model(cfg)
        build_instruments(cfg)
        duration = auto_duration(model) if cfg.run.duration == "auto" else cfg.run.duration
        checks.estimate_resources(model.system(), duration, build_probes(cfg), dt=cfg.run.dt,
                                  integrator=cfg.run.integrator)
        event("accepted")
    except hc.ConfigError as exc:
        event(f"refused: {exc.field.split('[')[0]}")
        head = exc.field.split(".")[0].split("[")[0]
        assert head in SECTIONS | set(data) or exc.field == "config", exc
        assert exc.message and "\n\n" not in exc.message
