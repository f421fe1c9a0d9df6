"""The striker and the beads of one run as particles: where they are, how fast they move and
the force on each, sample by sample (what the H5MD and VTK writers share).

Geometry (docs/conventions.rst): the chain lies along x, bead 1's left side at x = 0 where the
striker touches it at impact; the striker's centre is at x = -R_s; bead centres follow at the
axial distance of touching spheres (:func:`hertzchain.viz.common.bead_centres`); a bead's
perpendicular offset e_n (misaligned chains) is its y. Positions at time t are these places at
rest plus the recorded displacement along x.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
import xarray as xr

from ..errors import ConfigError
from ..viz.common import bead_centres, contact_positions

__all__ = ["Particles", "particles"]


@dataclass(frozen=True)
class Particles:
    """Bodies 0..N (0 = striker) of one run, on the result's time samples (SI units)."""

    time: np.ndarray              # (T,) s
    body: np.ndarray              # (B,) body numbers 0..N
    diameter: np.ndarray          # (B,) m
    rest: np.ndarray              # (B, 3) m, centres at impact
    position: np.ndarray          # (T, B, 3) m
    displacement: np.ndarray      # (T, B, 3) m, from the place at impact (as recorded: no rounding by rest + u)
    velocity: np.ndarray | None   # (T, B, 3) m s-1, None when not recorded
    force: np.ndarray | None      # (T, B, 3) N, net contact force; None without every contact force
    wall_x: float | None          # m, the wall's plane (None: no wall)


def striker_diameter(run: xr.Dataset) -> float:
    """The striker's diameter [m] from the result's ``model`` attribute (checked: a positive number)."""
    try:
        striker = json.loads(run.attrs["model"])["striker"]
    except (KeyError, TypeError, ValueError):
        striker = {}
    if striker is None:
        raise ConfigError("RESULT", "is a run without a striker (striker=None): the exports draw body 0 as the "
                          "striker and cannot place it")
    try:
        d = float(striker["diameter_mm"]) * 1e-3
    except (KeyError, TypeError, ValueError):
        raise ConfigError("RESULT", "holds no model attribute with the striker's diameter (striker.diameter_mm): "
                          "not a result written by hertzchain") from None
    if not (np.isfinite(d) and d > 0):
        raise ConfigError("RESULT", f"striker diameter {d!r} m is not a positive length")
    return d


def body_forces(run: xr.Dataset, n: int) -> np.ndarray | None:
    """Net contact force [N] along x on bodies 0..N, (T, N+1): contact j pushes body j + 1 towards
    the wall and body j back, F_k = C_{k-1} - C_k (C_{-1} = 0; C_N = the wall's, when there is one).
    None when the result does not hold every contact force (``probes.contacts``)."""
    if "contact_force" not in run or run.sizes.get("contact", -1) != run.sizes.get("contact_all", -2):
        return None
    c = np.asarray(run.contact_force.values, dtype=float)  # (T, N) without a wall, (T, N + 1) with one
    pad = np.zeros((c.shape[0], n + 2))
    pad[:, 1 : c.shape[1] + 1] = c
    return pad[:, :-1] - pad[:, 1:]


def particles(run: xr.Dataset, need_velocity: bool = False) -> Particles:
    """The bodies of ``run`` as particles; a ConfigError naming ``probes.positions`` (and
    ``probes.velocities`` when ``need_velocity``) when the result did not record them."""
    if "diameter" not in run or "displacement" not in run:
        raise ConfigError("RESULT", "holds no positions: rerun with --set probes.positions=true (and "
                          "probes.velocities=true for velocities) to export trajectories")
    if need_velocity and "velocity" not in run:
        raise ConfigError("RESULT", "holds no velocities: rerun with --set probes.velocities=true")
    phi = np.asarray(run.diameter.values, dtype=float)
    n = phi.size
    d_s = striker_diameter(run)
    rest = np.zeros((n + 1, 3))
    rest[0, 0] = -0.5 * d_s
    rest[1:, 0] = bead_centres(run)
    if "offset" in run:
        rest[1:, 1] = run.offset.values
    u = np.asarray(run.displacement.sel(body=slice(0, n)).values, dtype=float)  # (T, N + 1)
    position = np.repeat(rest[None], u.shape[0], axis=0)
    position[:, :, 0] += u
    displacement = np.zeros_like(position)
    displacement[:, :, 0] = u
    velocity = None
    if "velocity" in run:
        velocity = np.zeros_like(position)
        velocity[:, :, 0] = run.velocity.sel(body=slice(0, n)).values
    f = body_forces(run, n)
    force = None
    if f is not None:
        force = np.zeros_like(position)
        force[:, :, 0] = f
    has_wall = run.sizes.get("contact_all", 0) == n + 1
    return Particles(time=np.asarray(run.time.values, dtype=float), body=np.arange(n + 1),
                     diameter=np.concatenate([[d_s], phi]), rest=rest, position=position,
                     displacement=displacement, velocity=velocity,
                     force=force, wall_x=float(contact_positions(run)[n]) if has_wall else None)
