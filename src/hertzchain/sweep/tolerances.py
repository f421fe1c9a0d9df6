"""Manufacturing tolerances: the seeded random deviations that make a sweep's members differ.

The statistical model (``[sweep] tolerances = {...}``; every value a standard deviation with
``distribution = "normal"``, a half-width with ``"uniform"``):

- **Diameters.** Bead n of nominal diameter phi_n gets phi_n + sigma_n zeta_n with
  sigma_n = sqrt((diameter_rel_n phi_n)^2 + (diameter_abs_mm_n)^2): a relative part (a scale
  error) and an absolute part (a grinding tolerance in mm) that add as independent errors. With
  only relative tolerances the value is computed as phi_n (1 + diameter_rel_n z_n), the same
  number up to rounding.
- **Production lots** (``correlation = rho`` in [0, 1]). Beads made in one lot share part of
  their error: zeta_n = sqrt(rho) L_lot(n) + sqrt(1 - rho) z_n, with one deviate L per lot and
  one z per bead, all independent. Each bead keeps its standard deviation sigma_n, and two beads
  of one lot (one nominal diameter) correlate by exactly rho: rho = 0 (default) is independent
  beads, rho = 1 a lot whose beads are all off by the same amount. ``lot = "size"`` (default):
  the beads of one nominal diameter and material come from one lot (the uniform part of a tapered
  chain is one lot, each tapered size its own); ``lot = "chain"``: every bead of the chain from
  one lot. With ``distribution = "uniform"`` the lot and bead parts are each uniform: the
  variance and the correlation are as above, but the sum is no longer uniform (it may reach
  (sqrt(rho) + sqrt(1 - rho)) sigma_n).
- **Offsets** of the bead centres from the axis: e_n + offset_mm_n z'_n [mm], independent per bead.
- **Impact velocity**: v + sigma_v y with sigma_v = sqrt((velocity_rel v)^2 + velocity_abs^2), one
  y per member.

``diameter_rel``, ``diameter_abs_mm`` and ``offset_mm`` are one value for every bead or a list of
one value per bead (bead 1 first). The deviates of member i come from NumPy generators seeded by
(seed, i, stream): a member is the same whatever ``n`` or ``chunk_size`` is, and each kind of
tolerance has its own stream, so adding one leaves the others' draws alone (stream 1: z and z'
for every member; stream 2: the absolute diameter parts and the lots; stream 3: the velocity).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from ..errors import ConfigError

__all__ = ["Tolerances", "apply_to_model", "apply_to_ensemble", "perturb"]


def _per_bead_field(name: str, low: float, high: float, unit: str):
    def check(cls, value):
        values = value if isinstance(value, list) else [value]
        if isinstance(value, list) and not value:
            raise ValueError("needs one value per bead, got an empty list")
        for v in values:
            if not (low <= v < high):
                raise ValueError(f"must be in [{low:g}, {high:g}){unit}, got {v!r}")
        return value
    return field_validator(name)(check)


class Tolerances(BaseModel):
    """Per-bead and per-member random deviations (manufacturing tolerances); see the module docstring."""

    # strict like the run config: no booleans or strings as numbers, no NaN
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)

    diameter_rel: float | list[float] = Field(default=0.0, description="relative diameter deviation (1 sigma)")
    diameter_abs_mm: float | list[float] = Field(default=0.0, description="absolute diameter deviation, mm (1 sigma)")
    offset_mm: float | list[float] = Field(default=0.0, description="perpendicular offset deviation, mm (1 sigma)")
    velocity_rel: float = Field(default=0.0, ge=0, lt=0.5, description="relative impact velocity deviation")
    velocity_abs: float = Field(default=0.0, ge=0, le=1e3, description="impact velocity deviation, m/s")
    correlation: float = Field(default=0.0, ge=0, le=1, description="correlation of beads of one lot")
    lot: Literal["size", "chain"] = "size"
    distribution: Literal["normal", "uniform"] = "normal"
    seed: int = Field(default=0, ge=0, le=2**63 - 1)

    _rel = _per_bead_field("diameter_rel", 0.0, 0.1, "")
    _abs = _per_bead_field("diameter_abs_mm", 0.0, 1e3, " mm")
    _off = _per_bead_field("offset_mm", 0.0, 1e3, " mm")

    @property
    def has_abs(self) -> bool:
        """Whether absolute diameter parts or lots are drawn (stream 2)."""
        return _any(self.diameter_abs_mm) or self.correlation > 0

    @property
    def has_velocity(self) -> bool:
        """Whether the impact velocity varies (stream 3)."""
        return self.velocity_rel > 0 or self.velocity_abs > 0


def _any(x: float | list[float]) -> bool:
    return any(v > 0 for v in x) if isinstance(x, list) else x > 0


def _per_bead(tol: Tolerances, name: str, n: int) -> float | np.ndarray:
    value = getattr(tol, name)
    if not isinstance(value, list):
        return value
    if len(value) != n:
        raise ConfigError(f"sweep.tolerances.{name}", f"has {len(value)} values, one per bead, but the chain has "
                          f"{n} beads")
    return np.array(value, dtype=float)


def _draw(tol: Tolerances, rng: np.random.Generator, shape) -> np.ndarray:
    return rng.standard_normal(shape) if tol.distribution == "normal" else rng.uniform(-1.0, 1.0, shape)


def _lot_first(diameters: np.ndarray, materials: np.ndarray, lot: str) -> np.ndarray:
    """Per member and bead, the index of the first bead of its lot, shape (M, N)."""
    m, n = diameters.shape
    if lot == "chain":
        return np.zeros((m, n), dtype=np.int64)
    same = (diameters[:, :, None] == diameters[:, None, :]) & (materials[:, :, None] == materials[:, None, :])
    return np.argmax(same, axis=2)  # the first True: the lowest bead index of the same size and material


def perturb(tol: Tolerances, members, diameters: np.ndarray, offsets: np.ndarray, materials: np.ndarray,
            velocity: np.ndarray) -> dict[str, np.ndarray]:
    """The perturbed arrays of some members, drawn from (seed, member index).

    Parameters
    ----------
    tol : Tolerances
        The tolerances.
    members : sequence of int
        Member index of each row (its draws depend on it alone).
    diameters, offsets : numpy.ndarray
        Nominal diameters and offsets [m], shape (M, N).
    materials : numpy.ndarray
        An integer per bead that is equal for beads of one material, shape (M, N) (lots).
    velocity : numpy.ndarray
        Nominal impact velocities [m/s], shape (M,).

    Returns
    -------
    dict
        ``diameters`` and, when they vary, ``offsets`` and ``striker_velocity``.
    """
    m, n = diameters.shape
    z = np.empty((m, 2, n))
    for r, i in enumerate(members):
        z[r] = _draw(tol, np.random.default_rng([tol.seed, int(i), 1]), (2, n))
    rel = _per_bead(tol, "diameter_rel", n)
    if not tol.has_abs:
        d = diameters * (1.0 + rel * z[:, 0])
    else:
        a = np.empty((m, 2, n))
        for r, i in enumerate(members):
            a[r] = _draw(tol, np.random.default_rng([tol.seed, int(i), 2]), (2, n))
        sigma = np.hypot(rel * diameters, _per_bead(tol, "diameter_abs_mm", n) * 1e-3)
        rho = tol.correlation
        # z_n for the relative part, a_n for the absolute one: together one deviate of variance 1
        bead = (rel * diameters * z[:, 0] + _per_bead(tol, "diameter_abs_mm", n) * 1e-3 * a[:, 0])
        with np.errstate(invalid="ignore", divide="ignore"):
            bead = np.where(sigma > 0, bead / sigma, 0.0)
        lots = np.take_along_axis(a[:, 1], _lot_first(diameters, materials, tol.lot), axis=1)
        zeta = math.sqrt(rho) * lots + math.sqrt(1.0 - rho) * bead if rho > 0 else bead
        d = diameters + sigma * zeta
    out = {"diameters": d}
    off = _per_bead(tol, "offset_mm", n)
    if _any(tol.offset_mm):
        out["offsets"] = offsets + off * 1e-3 * z[:, 1]
    if tol.has_velocity:
        y = np.array([_draw(tol, np.random.default_rng([tol.seed, int(i), 3]), 1)[0] for i in members])
        out["striker_velocity"] = velocity + np.hypot(tol.velocity_rel * velocity, tol.velocity_abs) * y
    return out


def _material_ids(materials) -> np.ndarray:
    ids: dict[int, int] = {}
    return np.array([ids.setdefault(id(x), len(ids)) for x in materials], dtype=np.int64)


def apply_to_model(model, tol: Tolerances, index: int):
    """``model`` with the deviations of member ``index``.

    Parameters
    ----------
    model : hertzchain.model.Model
        The nominal member.
    tol : Tolerances
        The tolerances.
    index : int
        The member's index (its draws depend on (seed, index) alone).

    Returns
    -------
    hertzchain.model.Model
        The perturbed member.

    Raises
    ------
    ConfigError
        (``sweep.tolerances``) when the deviations make an invalid chain (a negative diameter...).
    """
    from ..chain import Chain

    chain = model.chain
    new = perturb(tol, [index], chain.diameters[None, :], chain.offsets[None, :],
                  _material_ids(chain.materials)[None, :], np.array([model.striker.velocity]))
    try:
        out = replace(model, chain=Chain(new["diameters"][0], chain.materials,
                                         new["offsets"][0] if "offsets" in new else chain.offsets))
        if "striker_velocity" in new:
            out = replace(out, striker=replace(model.striker, velocity=float(new["striker_velocity"][0])))
        return out
    except ConfigError as exc:
        raise ConfigError("sweep.tolerances", f"member {index}: {exc.field}: {exc.message}") from None


def apply_to_ensemble(ens, tol: Tolerances, members):
    """The members of ``ens`` (row r is member ``members[r]``) with their deviations.

    Parameters
    ----------
    ens : hertzchain.integrate.batch.ensemble.Ensemble
        The nominal members.
    tol : Tolerances
        The tolerances.
    members : sequence of int
        Member index of each row.

    Returns
    -------
    hertzchain.integrate.batch.ensemble.Ensemble
        The perturbed members; member r is ``apply_to_model(ens.model(r), tol, members[r])``.

    Raises
    ------
    ConfigError
        (``sweep.tolerances``) naming the first member whose deviations make an invalid chain.
    """
    new = perturb(tol, members, ens.diameters, ens.offsets, np.asarray(ens.bead_material),
                  ens.striker_velocity)
    try:
        return ens.replace(**new)
    except ConfigError as exc:
        raise ConfigError("sweep.tolerances", f"{exc.field}: {exc.message}") from None
