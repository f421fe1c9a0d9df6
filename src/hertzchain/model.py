"""The physical model: chain + striker + wall + contact law (+ precompression), and its flat arrays.

:class:`Model` is what a user builds; :meth:`Model.system` turns it into the unit-free SI arrays
(:class:`System`) that the compiled integrators and the scipy reference share, so both integrate
exactly the same equations (paper eq. 1 with per-contact Hertz constants).

Bodies (see docs/conventions.rst): 0 = striker, 1..N = beads, N + 1 = wall (a ghost body that never
moves; with no wall its contact has kappa = 0). Contact j joins bodies j and j + 1, j = 0..N.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from .chain import Chain
from .contact import LAW_CODES, Dashpot, Elastic, Elastoplastic, ScaledViscoelastic, Viscoelastic
from .errors import ConfigError
from .materials import Material, get_material

__all__ = ["Striker", "Wall", "Model", "System"]


@dataclass(frozen=True)
class Striker:
    """The impacting sphere (body 0), touching bead 1 at t = 0.

    Parameters
    ----------
    diameter
        Striker diameter [m] (the paper uses 8 mm).
    velocity
        Impact velocity [m/s], towards the chain (> 0).
    material
        Striker material (default: AISI 52100).
    """

    diameter: float = 8e-3
    velocity: float = 0.5
    material: Material | str = "AISI52100"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.diameter) and self.diameter > 0):
            raise ConfigError("striker.diameter_mm", f"must be a positive number, got {self.diameter * 1e3!r} mm")
        if not (math.isfinite(self.velocity) and self.velocity > 0):
            raise ConfigError("striker.velocity", f"must be a positive speed in m/s (towards the chain), got {self.velocity!r}")
        object.__setattr__(self, "material", get_material(self.material))

    @property
    def mass(self) -> float:
        """Striker mass rho pi phi^3 / 6 [kg]."""
        return self.material.density * math.pi * self.diameter**3 / 6.0


@dataclass(frozen=True)
class Wall:
    """What ends the chain after bead N (contact N joins bead N and the wall).

    Parameters
    ----------
    kind : {"flat", "none"}
        ``"flat"`` (default): an immovable flat (radius of curvature infinite, 1/R' = 0 in paper
        eq. 1); ``"none"``: a free end (contact N carries no force).
    material : str or Material, optional
        Material of the flat's cap (Young's modulus [Pa], Poisson ratio); the chain's last bead
        material when None, like the paper's sensor cap.
    """

    kind: Literal["flat", "none"] = "flat"
    material: Material | str | None = None

    def __post_init__(self) -> None:
        if self.kind not in ("flat", "none"):
            raise ConfigError("wall.type", f"must be 'flat' or 'none', got {self.kind!r}")
        if self.material is not None:
            object.__setattr__(self, "material", get_material(self.material))

    @property
    def present(self) -> bool:
        return self.kind != "none"


@dataclass(frozen=True)
class System:
    """Flat SI arrays of a model, as the compiled kernels take them. See :meth:`Model.system`.

    Shapes: N beads, ``nb = N + 1`` moving bodies, ``N + 2`` bodies with the ghost wall,
    ``N + 1`` contact slots (the last one has kappa = 0 when there is no wall).
    """

    mass: np.ndarray        # (N+2,) kg; wall ghost: inf
    inv_mass: np.ndarray    # (N+2,) 1/kg; wall ghost: 0
    kappa: np.ndarray       # (N+1,) N/m^1.5
    damping: np.ndarray     # (N+1,) A [s] (viscoelastic) or gamma [N s/m] (dashpot)
    d0: np.ndarray          # (N+1,) initial overlap [m] (precompression)
    de: np.ndarray          # (N+1,) perpendicular offset difference e_{j+1} - e_j [m]
    dx0: np.ndarray         # (N+1,) initial axial distance of centres of misaligned pairs [m]
    rsum: np.ndarray        # (N+1,) R_j + R_{j+1} [m]
    fext: np.ndarray        # (N+2,) constant external force [N] (precompression push on bead 1)
    u0: np.ndarray          # (N+2,) initial displacement [m]
    v0: np.ndarray          # (N+2,) initial velocity [m/s]
    law: int                # LAW_CODES
    misaligned: bool
    has_wall: bool
    yield_force: np.ndarray  # (N+1,) F_Y per contact [N] (inf when not defined)

    @property
    def n_beads(self) -> int:
        return self.mass.size - 2

    @property
    def n_contacts(self) -> int:
        """Number of real contacts: N + 1 with a wall, N without."""
        return self.n_beads + (1 if self.has_wall else 0)

    @property
    def general(self) -> bool:
        """True when the slower general force loop is needed (dissipation or offsets)."""
        return self.law != 0 or self.misaligned

    def yield_overlap(self) -> np.ndarray:
        """Overlap delta_y [m] at which every contact reaches its elastic limit, (N+1,).

        F_Y = kappa delta_y^(3/2) (:func:`hertzchain.contact.yield_force`, Thornton's F_y with
        p_y = 1.5 sigma_Y); inf where no yield stress is given or there is no contact.
        """
        kap = self.kappa
        ok = (kap > 0) & np.isfinite(self.yield_force)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(ok, (self.yield_force / np.where(ok, kap, 1.0)) ** (2.0 / 3.0), np.inf)

    def max_overlap(self) -> np.ndarray:
        """Upper bound of every contact's overlap [m] over the whole run, (N+1,).

        All the energy available (striker kinetic energy + precompression energy) put into one
        contact: (2/5) kappa delta^(5/2) <= E, plus the static overlap d0. Contacts with kappa = 0
        (no wall) get 0. For the elastic-plastic law the energy goes along Thornton's loading
        curve (softer than Hertz past the yield overlap, so deeper), and the precompression
        energy counted is the work along it.
        """
        energy = 0.5 * self.mass[0] * self.v0[0] ** 2
        kap = self.kappa
        if self.law == LAW_CODES["elastoplastic"]:
            from .contact import thornton_loading_overlap, thornton_loading_work

            dy = self.yield_overlap()
            energy += float(np.sum(np.where(kap > 0, thornton_loading_work(self.d0, kap, dy), 0.0)))
            return thornton_loading_overlap(energy, kap, dy) + self.d0
        energy += float(np.sum(0.4 * kap * self.d0**2.5))
        with np.errstate(divide="ignore"):
            return np.where(kap > 0, (2.5 * energy / np.where(kap > 0, kap, 1.0)) ** 0.4, 0.0) + self.d0

    def damping_coefficients(self, overlap: np.ndarray) -> np.ndarray:
        """Linear damping coefficient c_j [N s/m] of every contact at overlaps ``overlap`` [m], (N+1,).

        The dissipative force is c_j d(delta)/dt: c = gamma for the dashpot, c = kappa A delta^(1/2)
        for Kuwabara-Kono (zero for the elastic law and where kappa = 0).
        """
        if self.law == LAW_CODES["dashpot"]:
            return np.where(self.kappa > 0, self.damping, 0.0)
        if self.law in (LAW_CODES["viscoelastic"], LAW_CODES["elastoplastic"]):
            # elastic-plastic: A kappa_p (delta - delta_p)^(1/2) <= A kappa delta^(1/2)
            return self.kappa * self.damping * np.sqrt(np.maximum(overlap, 0.0))
        return np.zeros_like(self.kappa)

    def max_frequency(self) -> float:
        """Upper estimate of the highest angular frequency omega_max [rad/s] the run can reach,
        damping included: the time step must satisfy omega_max dt < 2 for Verlet to be stable.

        Each contact's overlap is bounded by :meth:`max_overlap`; the tangent stiffness
        k = (3/2) kappa delta^(1/2) then bounds the linearised stiffness matrix, and Gershgorin's
        theorem bounds its highest eigenvalue: omega^2 <= max_i 2 (k_left + k_right) / m_i. The
        damping coefficients c (:meth:`damping_coefficients`) are bounded the same way,
        beta_i = 2 (c_left + c_right) / m_i, and explicit damping lowers the stable step of a
        damped oscillator to 2 / (sqrt(omega^2 + beta^2 / 4) + beta / 2) (central differences
        with damping ratio beta / (2 omega)), which is 2 m / gamma for a bead held only by
        dashpots: omega_max is taken as max_i sqrt(omega_i^2 + beta_i^2 / 4) + beta_i / 2.
        """
        dmax = self.max_overlap()
        k = 1.5 * self.kappa * np.sqrt(dmax)
        c = self.damping_coefficients(dmax)
        nb = self.n_beads + 1
        omega2 = 2.0 * (np.concatenate([[0.0], k[: nb - 1]]) + k[:nb]) * self.inv_mass[:nb]
        beta = 2.0 * (np.concatenate([[0.0], c[: nb - 1]]) + c[:nb]) * self.inv_mass[:nb]
        return float(np.max(np.sqrt(omega2 + 0.25 * beta**2) + 0.5 * beta))


def _material_columns(materials: list[Material]) -> tuple[np.ndarray, np.ndarray]:
    """Per-body compliance theta [1/Pa] and yield stress [Pa] (NaN when not given)."""
    index: dict[int, int] = {}
    unique: list[Material] = []
    rows = np.empty(len(materials), dtype=np.int64)
    for i, mat in enumerate(materials):
        k = index.setdefault(id(mat), len(unique))
        if k == len(unique):
            unique.append(mat)
        rows[i] = k
    theta = np.array([m.theta for m in unique])
    sigma = np.array([np.nan if m.yield_stress is None else m.yield_stress for m in unique])
    return theta[rows], sigma[rows]


@dataclass(frozen=True)
class Model:
    """A chain hit by a striker, ended by a wall, with a contact law.

    Parameters
    ----------
    chain
        The beads.
    striker
        The impacting sphere (body 0).
    wall
        The end condition (default: immovable flat of the chain's material).
    law
        Contact law: :class:`Elastic` (paper eq. 1), :class:`Viscoelastic`, :class:`ScaledViscoelastic`,
        :class:`Dashpot` or :class:`Elastoplastic` (Thornton 1997).
    precompression
        Static force [N] squeezing beads 1..N against the wall before impact (0 = the paper's
        "barely touching" chain). Needs a wall.
    """

    chain: Chain
    striker: Striker = field(default_factory=Striker)
    wall: Wall = field(default_factory=Wall)
    law: Elastic | Viscoelastic | ScaledViscoelastic | Dashpot | Elastoplastic = field(default_factory=Elastic)
    precompression: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.precompression) and self.precompression >= 0):
            raise ConfigError("chain.precompression", f"must be a force >= 0 in N, got {self.precompression!r}")
        if self.precompression > 0 and not self.wall.present:
            raise ConfigError("chain.precompression", "a static precompression needs a wall to push against")
        if self.precompression > 0 and not self.chain.is_aligned:
            raise ConfigError("chain.precompression", "precompression together with bead offsets is not supported")
        # The striker's contact obeys the same head-on rule as the chain's (Chain checks beads n, n+1):
        # the striker flies along the axis, so bead 1's offset e_1 must stay below (R_s + R_1) / 2;
        # past R_s + R_1 it would miss the chain and the run would report 0 N.
        e1, reach = abs(float(self.chain.offsets[0])), 0.5 * (self.striker.diameter / 2 + self.chain.radii[0])
        if e1 >= reach:
            raise ConfigError("chain.offsets", f"bead 1 is offset by {e1:.3g} m from the striker's line of flight, "
                              f"more than half the sum of their radii ({reach:.3g} m); the striker would not "
                              "hit it head-on (or would miss the chain)")

    @property
    def wall_material(self) -> Material | None:
        if not self.wall.present:
            return None
        return self.wall.material or self.chain.materials[-1]

    def contact_radii(self) -> list[tuple[float, float | None]]:
        """(R, R') of every contact 0..N (R' None = flat)."""
        r = [self.striker.diameter / 2] + list(self.chain.radii)
        pairs: list[tuple[float, float | None]] = [(r[j], r[j + 1]) for j in range(self.chain.n_beads)]
        pairs.append((r[-1], None))
        return pairs

    def contact_materials(self) -> list[tuple[Material, Material | None]]:
        mats = [self.striker.material] + list(self.chain.materials)
        out: list[tuple[Material, Material | None]] = [(mats[j], mats[j + 1]) for j in range(self.chain.n_beads)]
        out.append((mats[-1], self.wall_material))
        return out

    def system(self) -> System:
        """Flatten the model into SI arrays (see :class:`System`)."""
        n = self.chain.n_beads
        mass = np.empty(n + 2)
        mass[0] = self.striker.mass
        mass[1 : n + 1] = self.chain.masses
        mass[n + 1] = np.inf
        inv_mass = np.zeros(n + 2)
        inv_mass[: n + 1] = 1.0 / mass[: n + 1]

        # Hertz constants and elastic limits of every contact, vectorised over the chain (a Python
        # loop over contact_radii() took ~4 s for 1e6 beads): the formulas of contact.hertz_constant
        # and contact.yield_force, with bodies 0..N and the wall as body N + 1 (flat: 1/R' = 0).
        r = np.concatenate([[self.striker.diameter / 2], self.chain.radii])
        theta, sigma = _material_columns([self.striker.material, *self.chain.materials])
        inv_r = 1.0 / r[:-1] + 1.0 / r[1:]
        t_sum = theta[:-1] + theta[1:]
        s_min = np.fmin(sigma[:-1], sigma[1:])  # weaker material; NaN = no yield stress given
        if self.wall.present:
            wall_theta, wall_sigma = _material_columns([self.wall_material])
            inv_r = np.append(inv_r, 1.0 / r[-1])
            t_sum = np.append(t_sum, theta[-1] + wall_theta[0])
            s_min = np.append(s_min, np.fmin(sigma[-1], wall_sigma[0]))
        kappa = np.zeros(n + 1)
        fy = np.full(n + 1, np.inf)
        m = inv_r.size
        kappa[:m] = 1.0 / (t_sum * np.sqrt(inv_r))
        c = 3.0 * (1.0 / inv_r) / (4.0 * (0.75 / t_sum))  # 3 R* / (4 E*), E* = 3 / (4 (theta + theta'))
        with np.errstate(invalid="ignore"):
            fy[:m] = np.where(np.isnan(s_min), np.inf, (math.pi * s_min) ** 3 * c**2)

        # No damping where there is no contact (the free end's slot has kappa = 0): a dashpot there
        # would push the last bead against a wall that does not exist (F = gamma d(delta)/dt).
        damping = np.where(kappa > 0, float(self.law.parameter), 0.0)
        if hasattr(self.law, "contact_damping"):
            # Size-scaled law: A_j from the pair's reduced mass (the wall is immovable: mu = m_N).
            mu = 1.0 / (inv_mass[: n + 1] + inv_mass[1:])
            damping = self.law.contact_damping(mu, kappa)
        # Precompression: every contact of the chain (not the striker's) carries F0 statically.
        d0 = np.zeros(n + 1)
        fext = np.zeros(n + 2)
        if self.precompression > 0:
            d0[1:] = (self.precompression / kappa[1:]) ** (2.0 / 3.0)
            fext[1] = self.precompression
            if self.law.name == "elastoplastic":
                # statically loaded along Thornton's loading curve: past F_Y the line F_y + slope (d - dy)
                with np.errstate(invalid="ignore"):
                    dy = (fy[1:] / kappa[1:]) ** (2.0 / 3.0)
                    over = self.precompression > fy[1:]
                    plastic = dy + (self.precompression - fy[1:]) / (1.5 * kappa[1:] * np.sqrt(dy))
                d0[1:] = np.where(over, plastic, d0[1:])

        e = np.concatenate([[0.0], self.chain.offsets, [0.0]])
        de = np.diff(e)
        de[n] = 0.0  # a flat wall is unaffected by the last bead's offset (docs/conventions.rst)
        r = np.concatenate([[self.striker.diameter / 2], self.chain.radii, [0.0]])
        rsum = r[:-1] + r[1:]
        # Misaligned neighbours start touching along their line of centres (docs/conventions.rst).
        dx0 = np.sqrt(np.maximum(rsum**2 - de**2, 0.0))

        v0 = np.zeros(n + 2)
        v0[0] = self.striker.velocity
        return System(mass=mass, inv_mass=inv_mass, kappa=kappa, damping=damping, d0=d0, de=de, dx0=dx0,
                      rsum=rsum, fext=fext, u0=np.zeros(n + 2), v0=v0, law=LAW_CODES[self.law.name],
                      misaligned=bool(np.any(de != 0.0)), has_wall=self.wall.present, yield_force=fy)

    def describe(self) -> dict:
        """Plain-data description of the model (stored in result attributes)."""
        law = {"law": self.law.name}
        if self.law.name == "viscoelastic":
            law["A"] = self.law.A
        elif self.law.name == "viscoelastic_scaled":
            law.update(A=self.law.A, reference_diameter_mm=self.law.diameter * 1e3,
                       reference_material=self.law.material.name)
        elif self.law.name == "dashpot":
            law["gamma"] = self.law.gamma
        elif self.law.name == "elastoplastic":
            from .contact import LIMITING_PRESSURE_FACTOR

            law.update(A=self.law.A, limiting_pressure_over_yield_stress=LIMITING_PRESSURE_FACTOR)
            if self.law.diameter is not None:
                law.update(reference_diameter_mm=self.law.diameter * 1e3, reference_material=self.law.material.name)
        return {
            "chain": self.chain.describe(),
            "striker": {"diameter_mm": self.striker.diameter * 1e3, "velocity": self.striker.velocity,
                        "material": self.striker.material.name},
            "wall": {"type": self.wall.kind, "material": None if self.wall_material is None else self.wall_material.name},
            "contact": law,
            "precompression": self.precompression,
        }
