"""A run's chain as LAMMPS input (https://docs.lammps.org): a data file of the striker and the
beads at impact, and beside it the input script ``in.NAME`` that runs the impact.

The model is hertzchain's (docs/conventions.rst), in LAMMPS' GRANULAR package:

- ``units si``, ``atom_style sphere``: one atom per body (atom 1 = the striker, atoms 2..N+1 =
  beads 1..N) on the x axis, touching at impact, each atom's density chosen so its mass is the
  body's (m = rho pi phi^3 / 6); one atom type per material;
- ``pair_style granular`` with ``hertz/material E 0 nu`` and a frictionless ``tangential
  linear_nohistory 0 0``: F = (4/3) E* sqrt(R*) delta^(3/2) (paper eq. 1). For two atoms of one
  type LAMMPS takes E* = E / (2 (1 - nu^2)), the materials' own E and nu; a pair of types is
  given E = 2 E* and nu = 0 with 1/E* = (1 - nu_i^2)/E_i + (1 - nu_j^2)/E_j, Hertz's mixture;
- the wall as ``fix wall/gran`` on the plane past bead N, the same model (E = 2 E* and nu = 0 of
  bead N's material against the wall's when they differ; R* = R_N for a sphere on a flat);
- ``fix nve/sphere`` (velocity Verlet, as hertzchain's engine) at the run's time step (its
  smallest, for an adaptive run), and
  ``fix setforce NULL 0 0`` holding the beads on their lines (hertzchain's chain is 1D);
- the wall force, written every sample interval to ``wall_force.NAME.txt`` (time [s], force [N])
  through ``compute reduce`` of the wall's per-atom contact forces.

Contacts are elastic: a dissipative law of the run (a dashpot, Kuwabara-Kono, Thornton's
plasticity) has no one-to-one LAMMPS model and is left out, which the script's header says.
Protected bodies, gravity, precompression, elements other than spheres, strikers with a flat
face and laws whose force is not Hertz's (the registry's ``exponent`` other than 3/2) are refused
(naming them).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import xarray as xr

from .. import __version__
from ..errors import ConfigError
from ..materials import Material, get_material
from ..viz.common import bead_centres, contact_positions
from .bodies import striker_diameter

__all__ = ["write_lammps", "input_name"]


def input_name(path: Path) -> Path:
    """The input script written beside the data file ``path``: ``in.NAME`` (NAME = its stem)."""
    return path.with_name(f"in.{path.stem}")


def _model(run: xr.Dataset) -> dict:
    try:
        model = json.loads(run.attrs["model"])
        assert isinstance(model, dict) and isinstance(model.get("chain"), dict)
    except (KeyError, TypeError, ValueError, AssertionError):
        raise ConfigError("RESULT", "holds no model attribute (chain, striker, wall): not a result written by "
                          "hertzchain") from None
    return model


def _refuse_what_lammps_lacks(model: dict) -> None:
    wall = model.get("wall") or {}
    striker = model.get("striker") or {}
    reasons = []
    if wall.get("type") == "body":
        reasons.append("a protected body (wall.type = \"body\")")
    if model.get("gravity"):
        reasons.append("gravity (chain.gravity)")
    if model.get("precompression"):
        reasons.append("precompression (chain.precompression)")
    if model["chain"].get("elements"):
        reasons.append("elements other than spheres (chain.elements)")
    if striker.get("shape", "sphere") != "sphere" or striker.get("radius_of_curvature_mm") is not None:
        reasons.append("a striker that is not a sphere (striker.shape, striker.radius_of_curvature_mm)")
    if reasons:
        raise ConfigError("--out", "a LAMMPS data file holds a chain of spheres hitting a flat wall (or a free "
                          f"end); this result has {', '.join(reasons)}")


def _resolver(run: xr.Dataset):
    """Material by name: the run's own ``[materials]`` table first (every number checked), then
    the catalogue."""
    try:
        config = json.loads(run.attrs.get("config", "{}"))
    except (TypeError, ValueError):
        config = {}
    table = config.get("materials") if isinstance(config, dict) else None
    table = table if isinstance(table, dict) else {}

    def resolve(name) -> Material:
        if not isinstance(name, str):
            raise ConfigError("RESULT", f"material name {name!r} is not a name")
        entry = table.get(name)
        if not isinstance(entry, dict):
            return get_material(name)
        try:
            m = Material(name, float(entry["density"]), float(entry["young"]), float(entry["poisson"]))
        except (KeyError, TypeError, ValueError):
            raise ConfigError("RESULT", f"material {name!r} of the run's config lacks density, young or "
                              "poisson") from None
        if not (m.density > 0 and m.young > 0 and -1 < m.poisson < 0.5 and math.isfinite(m.density * m.young)):
            raise ConfigError("RESULT", f"material {name!r}: density, young or poisson out of range")
        return m

    return resolve


def _hertz_law(model: dict):
    """The run's contact law from the registry (hertzchain.laws); refused unless its elastic force
    is Hertz's (overlap^(3/2)), the one ``hertz/material`` applies."""
    from ..laws import get_law

    name = (model.get("contact") or {}).get("law")
    try:
        spec = get_law(name if isinstance(name, str) else "")
    except ConfigError:
        spec = None
    if spec is None or spec.exponent != 1.5:
        raise ConfigError("--out", f"LAMMPS' hertz/material applies Hertz's force (overlap^(3/2)); this run's contact "
                          f"law {name!r} is not a Hertz law hertzchain knows here")
    return spec


def _materials(run: xr.Dataset, model: dict, n: int) -> tuple[list[Material], Material | None]:
    """The materials of the striker and beads 1..N, and the flat wall's (None: no wall)."""
    resolve = _resolver(run)
    beads = model["chain"].get("materials")
    names = [beads] * n if isinstance(beads, str) else beads
    if not isinstance(names, list) or len(names) != n:
        raise ConfigError("RESULT", f"its model names {names!r} as the materials of {n} beads")
    mats = [resolve((model.get("striker") or {}).get("material")), *map(resolve, names)]
    wall = model.get("wall") or {}
    if wall.get("type", "flat") != "flat":
        return mats, None
    return mats, resolve(wall.get("material") or names[-1])


def _e_star(a: Material, b: Material) -> float:
    """Hertz's effective modulus [Pa] of two materials: 1/E* = (1 - nu_a^2)/E_a + (1 - nu_b^2)/E_b."""
    return 1.0 / ((1 - a.poisson**2) / a.young + (1 - b.poisson**2) / b.young)


def _check_stiffness(run: xr.Dataset, radius: np.ndarray, mats: list[Material], wall: Material | None) -> None:
    """The result's contact stiffnesses kappa_j must be those of Hertz spheres of its materials
    (paper eq. 1: kappa = (4/3) E* sqrt(R*)): what the LAMMPS model will apply."""
    if "kappa" not in run:
        return
    kappa = np.asarray(run.kappa.values, dtype=float)
    expected = [4 / 3 * _e_star(mats[j], mats[j + 1]) * math.sqrt(radius[j] * radius[j + 1] / (radius[j] + radius[j + 1]))
                for j in range(radius.size - 1)]
    if wall is not None:
        expected.append(4 / 3 * _e_star(mats[-1], wall) * math.sqrt(radius[-1]))
    want = np.asarray(expected[: kappa.size])
    bad = np.flatnonzero(~np.isclose(kappa[: want.size], want, rtol=1e-9, atol=0.0))
    if bad.size:
        j = int(bad[0])
        raise ConfigError("RESULT", f"contact {j}'s stiffness {kappa[j]:.6g} N/m^1.5 is not that of Hertz spheres "
                          f"of its materials ({expected[j]:.6g}): a LAMMPS data file holds spheres only")


def _num(x: float) -> str:
    return repr(float(x))


def write_lammps(run: xr.Dataset, path: Path) -> list[Path]:
    """Write ``run``'s chain as the LAMMPS data file ``path`` and the input script ``in.NAME``.

    Parameters
    ----------
    run : xarray.Dataset
        One run of a chain of spheres (any recorded signals: only the model and the run's time
        step, duration and sample interval are used).
    path : pathlib.Path
        The data file (``NAME.data``).

    Returns
    -------
    list of pathlib.Path
        The data file and the input script.
    """
    from ..fileio import write_text

    model = _model(run)
    _refuse_what_lammps_lacks(model)
    phi = np.asarray(run.diameter.values, dtype=float)
    n = phi.size
    d = np.concatenate([[striker_diameter(run)], phi])
    radius = d / 2
    mats, wall_mat = _materials(run, model, n)
    _check_stiffness(run, radius, mats, wall_mat)
    striker = model.get("striker") or {}
    mass = np.empty(n + 1)
    mass[0] = float(striker["mass"]) if "mass" in striker else mats[0].density * math.pi * d[0] ** 3 / 6
    mass[1:] = run.mass.values if "mass" in run else [m.density * math.pi * x**3 / 6 for m, x in zip(mats[1:], phi)]
    density = mass / (math.pi * d**3 / 6)
    x = np.concatenate([[-radius[0]], bead_centres(run)])
    y = np.concatenate([[0.0], run.offset.values if "offset" in run else np.zeros(n)])
    v0 = float(striker.get("velocity", 0.0))
    duration = float(run.attrs.get("duration", run.time.values[-1]))
    dt = float(run.attrs.get("dt", 0.0))
    if not (math.isfinite(dt) and dt > 0 and math.isfinite(duration) and duration > 0):
        raise ConfigError("RESULT", "holds no positive time step (dt) and duration: not a result of hertzchain's "
                          "Verlet engine")
    wall_x = float(contact_positions(run)[n]) if wall_mat is not None else None

    types, type_of = [], []
    for m in mats:
        if m not in types:
            types.append(m)
        type_of.append(types.index(m) + 1)
    reach = 2 * d.max() + abs(v0) * duration * 2  # room for the striker's rebound and the beads' motion
    side = d.max() + float(np.max(np.abs(y)))
    xhi = (wall_x if wall_x is not None else x[-1] + radius[-1]) + d.max()
    title = f"{n} beads, striker {d[0] * 1e3:g} mm at {v0:g} m/s"
    data = [f"LAMMPS data file written by hertzchain {__version__}: {title} (units si, atom_style sphere)", "",
            f"{n + 1} atoms", f"{len(types)} atom types", "",
            f"{_num(x[0] - reach)} {_num(xhi)} xlo xhi", f"{_num(-side)} {_num(side)} ylo yhi",
            f"{_num(-side)} {_num(side)} zlo zhi", "", "Atoms # sphere", ""]
    data += [f"{i + 1} {type_of[i]} {_num(d[i])} {_num(density[i])} {_num(x[i])} {_num(y[i])} 0.0" for i in range(n + 1)]
    data += ["", "Velocities", ""]
    data += [f"{i + 1} {_num(v0 if i == 0 else 0.0)} 0.0 0.0 0.0 0.0 0.0" for i in range(n + 1)]

    every = max(1, round(float(run.attrs.get("sample_interval", dt)) / dt))
    spec = _hertz_law(model)
    gran = "tangential linear_nohistory 0.0 0.0"
    script = [f"# LAMMPS input written by hertzchain {__version__}: {title}.",
              f"# Run it beside {path.name}: lmp -in {input_name(path).name}",
              "# Atom 1 is the striker, atoms 2..N+1 beads 1..N, on the x axis, touching at impact;",
              "# Hertz contacts F = (4/3) E* sqrt(R*) delta^(3/2) (hertzchain's paper eq. 1), velocity Verlet.",
              *([f"# hertzchain ran contact law {spec.name!r}: its dissipation has no LAMMPS counterpart here, "
                 "the contacts below are elastic."] if spec.dissipative or spec.plastic else []),
              "units           si", "dimension       3", "boundary        f f f", "atom_style      sphere",
              "atom_modify     map array", "comm_modify     vel yes", f"read_data       {path.name}", "",
              "pair_style      granular"]
    for i, a in enumerate(types, start=1):
        for j, b in enumerate(types, start=1):
            if j < i:
                continue
            if a == b:
                coeff = f"hertz/material {_num(a.young)} 0.0 {_num(a.poisson)}"
                note = f"# {a.name}: E [Pa], damping, nu"
            else:
                coeff = f"hertz/material {_num(2 * _e_star(a, b))} 0.0 0.0"
                note = f"# {a.name} on {b.name}: E = 2 E*, nu = 0"
            script.append(f"pair_coeff      {i} {j} {coeff} {gran}   {note}")
    script += [f"neighbor        {_num(0.05 * d.min())} bin", "neigh_modify    every 1 delay 0 check yes", ""]
    if wall_x is not None:
        assert wall_mat is not None  # (wall_x is set exactly when there is a wall)
        last = mats[-1]
        if last == wall_mat:
            coeff, note = f"hertz/material {_num(last.young)} 0.0 {_num(last.poisson)}", f"{last.name} on itself"
        else:
            coeff = f"hertz/material {_num(2 * _e_star(last, wall_mat))} 0.0 0.0"
            note = f"{last.name} on {wall_mat.name}: E = 2 E*, nu = 0"
        script += [f"# The flat wall past bead N ({note}).",
                   f"fix             wall all wall/gran granular {coeff} {gran} xplane NULL {_num(wall_x)} contacts",
                   "compute         wall_fx all reduce min f_wall[2]",
                   "variable        wall_force equal -c_wall_fx   # N, the force on the wall (paper's F_m signal)"]
    else:
        script += ["# A free end past bead N (no wall).", "variable        wall_force equal 0.0"]
    script += ["", "fix             integrate all nve/sphere",
               "fix             axis all setforce NULL 0.0 0.0   # beads held on their lines, as in hertzchain's 1D chain",
               f"timestep        {_num(dt)}", "variable        t equal time",
               f"fix             wall_out all print {every} \"${{t}} ${{wall_force}}\" file wall_force.{path.stem}.txt "
               "screen no title \"# time [s]  wall force [N]\"",
               "thermo_style    custom step time v_wall_force ke", f"thermo          {every * 100}",
               f"run             {math.ceil(duration / dt - 1e-9)}"]
    script_path = input_name(path)
    write_text(path, "\n".join(data) + "\n")
    write_text(script_path, "\n".join(script) + "\n")
    return [path, script_path]
