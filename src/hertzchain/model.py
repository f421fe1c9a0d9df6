"""The physical model: chain + striker + wall + contact law (+ precompression), and its flat arrays.

:class:`Model` is what a user builds; :meth:`Model.system` turns it into the unit-free SI arrays
(:class:`System`) that the compiled integrators and the scipy reference share, so both integrate
exactly the same equations (paper eq. 1 with per-contact Hertz constants).

Bodies (see docs/conventions.rst): 0 = striker, 1..N = beads, N + 1 = wall (a ghost body that never
moves; with no wall its contact has kappa = 0). Contact j joins bodies j and j + 1, j = 0..N.
"""

from __future__ import annotations

import json
import math
import numbers
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from .bounds import check_bound
from .chain import Chain
from .contact import Elastic
from . import plasticity  # noqa: F401  (attaches the elastoplastic law's maker: laws.spec.attach_maker)
from .errors import ConfigError
from .laws import law_of_code, spec_of
from .laws.spec import LawObject
from .laws.solve import overlap_at_energy, static_overlap
from .materials import Material, get_material, material_columns
from .strict import real

if TYPE_CHECKING:  # the drive's module loads only for a driven model
    from .crystal.drive import Drive

__all__ = ["Striker", "Wall", "Model", "System"]


def _positive(value, field_name: str, what: str) -> None:
    if isinstance(value, bool) or not (isinstance(value, numbers.Real) and math.isfinite(value) and float(value) > 0):
        raise ConfigError(field_name, f"must be {what}, got {value!r}")


@dataclass(frozen=True, init=False)
class Striker:
    """The impacting body (body 0), touching bead 1 at t = 0.

    Parameters
    ----------
    diameter
        Striker diameter [m] (the paper uses 8 mm).
    velocity
        Impact velocity [m/s], towards the chain (> 0).
    material
        Striker material (default: AISI 52100).
    mass
        Given mass [kg] (a drop hammer, an impactor of any build); None: the sphere's
        rho pi phi^3 / 6.
    shape : {"sphere", "flat"}
        Its face: a sphere of the striker's diameter (or of ``radius_of_curvature``), or a flat
        face, which meets bead 1 in a sphere-flat Hertz contact (1/R' = 0 in paper eq. 1).
    radius_of_curvature
        Radius [m] of a curved (spherical) striker face, e.g. a hammer's; None: the diameter / 2.
    given_mass
        The stored form of ``mass`` (what :func:`dataclasses.replace` passes on); give ``mass``.
    """

    diameter: float
    velocity: float
    material: Material
    shape: Literal["sphere", "flat"]
    radius_of_curvature: float | None
    given_mass: float | None

    def __init__(self, diameter: float = 8e-3, velocity: float = 0.5, material: Material | str = "AISI52100",
                 mass: float | None = None, shape: Literal["sphere", "flat"] = "sphere",
                 radius_of_curvature: float | None = None, *, given_mass: float | None = None) -> None:
        if mass is not None and given_mass is not None:
            raise ConfigError("striker.mass", "give mass only once")
        mass = given_mass if mass is None else mass
        # Strict types (True or "0.3" are not speeds); NumPy scalars are stored as floats.
        diameter = real(diameter, "striker.diameter", unit="m")
        velocity = real(velocity, "striker.velocity", unit="m/s")
        if not (math.isfinite(diameter) and diameter > 0):
            raise ConfigError("striker.diameter_mm", f"must be a positive number, got {diameter * 1e3!r} mm")
        if not (math.isfinite(velocity) and velocity > 0):
            raise ConfigError("striker.velocity", f"must be a positive speed in m/s (towards the chain), got {velocity!r}")
        mass = check_bound(mass, "mass", "striker.mass", "kg", allow_none=True)
        if shape not in ("sphere", "flat"):
            raise ConfigError("striker.shape", f"must be 'sphere' or 'flat', got {shape!r}")
        if radius_of_curvature is not None:
            if shape == "flat":
                raise ConfigError("striker.radius_of_curvature_mm", "a flat striker has no radius of curvature")
            _positive(radius_of_curvature, "striker.radius_of_curvature_mm", "a positive radius")
        for name, value in (("diameter", diameter), ("velocity", velocity), ("material", get_material(material)),
                            ("shape", shape), ("radius_of_curvature", radius_of_curvature), ("given_mass", mass)):
            object.__setattr__(self, name, value)

    @property
    def mass(self) -> float:
        """Striker mass [kg]: the given one, else rho pi phi^3 / 6."""
        if self.given_mass is not None:
            return self.given_mass
        return self.material.density * math.pi * self.diameter**3 / 6.0

    @property
    def face_radius(self) -> float | None:
        """Radius of curvature of the face that hits bead 1 [m]; None for a flat face."""
        if self.shape == "flat":
            return None
        return self.radius_of_curvature if self.radius_of_curvature is not None else self.diameter / 2

    @property
    def plain(self) -> bool:
        """True for the paper's kind of striker: a sphere of its own material, no given mass."""
        return self.shape == "sphere" and self.given_mass is None and self.radius_of_curvature is None

    def describe(self) -> dict:
        """Plain-data description (stored in result attributes)."""
        out: dict = {"diameter_mm": self.diameter * 1e3, "velocity": self.velocity, "material": self.material.name}
        if not self.plain:
            out.update(mass=self.mass, shape=self.shape,
                       radius_of_curvature_mm=None if self.face_radius is None else self.face_radius * 1e3)
        return out

    def __repr__(self) -> str:
        extra = ""
        if not self.plain:
            extra = f", {self.mass * 1e3:.4g} g" + (", flat face" if self.shape == "flat" else "")
        return f"Striker({self.diameter * 1e3:.4g} mm {self.material.name} at {self.velocity:.4g} m/s{extra})"


@dataclass(frozen=True)
class Wall:
    """What ends the chain after bead N (contact N joins bead N and the wall).

    Parameters
    ----------
    kind : {"flat", "none", "body"}
        ``"flat"`` (default): an immovable flat (radius of curvature infinite, 1/R' = 0 in paper
        eq. 1); ``"none"``: a free end (contact N carries no force); ``"body"``: a protected
        body, a rigid body of ``mass`` on a spring (``stiffness``) and a dashpot (``damping``)
        to the ground, whose face the chain presses on (body N + 1).
    material : str or Material, optional
        Material of the flat's cap or of the body's face (Young's modulus [Pa], Poisson ratio);
        the chain's first bead material when None (the base material of the chain: a bead
        changed at the wall's end does not change the wall).
    mass : float, optional
        The body's mass [kg] (``"body"`` only).
    stiffness : float
        The body's mount to the ground [N/m], >= 0 (0: a free body).
    damping : float
        The mount's dashpot [N s/m], >= 0.
    shape : {"flat", "sphere"}
        The body's face: flat (default) or a spherical cap of ``radius_of_curvature``.
    radius_of_curvature : float, optional
        Radius [m] of a spherical body face.
    """

    kind: Literal["flat", "none", "body"] = "flat"
    material: Material | str | None = None
    mass: float | None = None
    stiffness: float = 0.0
    damping: float = 0.0
    shape: Literal["flat", "sphere"] = "flat"
    radius_of_curvature: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in ("flat", "none", "body"):
            raise ConfigError("wall.type", f"must be 'flat', 'none' or 'body', got {self.kind!r}")
        if self.material is not None:
            object.__setattr__(self, "material", get_material(self.material))
        if self.kind != "body":
            for name, default in (("mass", None), ("stiffness", 0.0), ("damping", 0.0), ("shape", "flat"),
                                  ("radius_of_curvature", None)):
                if getattr(self, name) != default:
                    key = name + ("_mm" if name == "radius_of_curvature" else "")
                    raise ConfigError(f"wall.{key}", f"belongs to a protected body: set wall.type = 'body' "
                                      f"(this wall is '{self.kind}')")
            return
        if self.mass is None:
            raise ConfigError("wall.mass", "a protected body (wall.type = 'body') needs its mass in kg")
        for name, unit in (("mass", "kg"), ("stiffness", "N/m"), ("damping", "N s/m")):
            object.__setattr__(self, name, check_bound(getattr(self, name), name, f"wall.{name}", unit))
        if self.shape not in ("flat", "sphere"):
            raise ConfigError("wall.shape", f"must be 'flat' or 'sphere', got {self.shape!r}")
        if self.shape == "sphere":
            if self.radius_of_curvature is None:
                raise ConfigError("wall.radius_of_curvature_mm", "a spherical body face needs its radius of curvature")
            _positive(self.radius_of_curvature, "wall.radius_of_curvature_mm", "a positive radius")
        elif self.radius_of_curvature is not None:
            raise ConfigError("wall.radius_of_curvature_mm", "a flat face has no radius of curvature (shape = 'sphere')")

    @property
    def present(self) -> bool:
        """Whether there is a contact N (a flat wall or a body)."""
        return self.kind != "none"

    @property
    def is_body(self) -> bool:
        """Whether the chain ends on a protected body (a moving body N + 1)."""
        return self.kind == "body"

    @property
    def face_radius(self) -> float | None:
        """Radius of curvature of the face bead N presses on [m]; None for a flat."""
        return self.radius_of_curvature if self.shape == "sphere" else None

    def __repr__(self) -> str:
        text = f"Wall({self.kind!r}" + (f", {self.material.name}" if isinstance(self.material, Material) else "")
        if self.is_body:
            text += f", {self.mass:.4g} kg on {self.stiffness:.4g} N/m, {self.damping:.4g} N s/m"
        return text + ")"


@dataclass(frozen=True)
class System:
    """Flat SI arrays of a model, as the compiled kernels take them. See :meth:`Model.system`.

    Shapes: N beads, ``nb = N + 1`` moving bodies, ``N + 2`` bodies with the ghost wall,
    ``N + 1`` contact slots (the last one has kappa = 0 when there is no wall). A protected body
    (``body``) is body N + 1 itself: it moves (1/m = 1/M), held by its mount, a linear spring and
    dashpot to the ground that the engine treats as contact N + 1 (stiffness ``mount_k``, dashpot
    ``mount_c``, static deflection ``mount_d0``; it pulls as well as pushes). Mass-in-mass bodies
    carry an internal mass ``res_m`` on a spring ``res_k`` (bodies 0..N + 1; 0 where none).
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
    body: bool = False       # body N + 1 is a protected body (moves) instead of the immovable ghost
    mount_k: float = 0.0     # N/m, the body's mount (contact N + 1, linear, to the ground)
    mount_c: float = 0.0     # N s/m
    mount_d0: float = 0.0    # m, the mount's deflection at rest (its force k d0 carries the static load)
    res_m: np.ndarray | None = None   # (N+2,) kg, internal masses of mass-in-mass bodies (None: none)
    res_k: np.ndarray | None = None   # (N+2,) N/m, their springs
    #: elastoplastic law: its limiting pressure over the paper-consistent 1.5 sigma_Y (Elastoplastic.pressure_ratio)
    yield_pressure_ratio: float = 1.0

    @property
    def n_beads(self) -> int:
        return self.mass.size - 2

    @property
    def n_moving(self) -> int:
        """Bodies the engine moves: striker and beads, and the protected body when there is one."""
        return self.n_beads + (2 if self.body else 1)

    def static_forces(self) -> np.ndarray:
        """Force [N] every contact 0..N carries at rest, (N+1,): contact j holds the external forces
        of bodies 0..j (precompression, weights), 0 where there is no contact."""
        s = np.cumsum(self.fext[: self.n_beads + 1])
        return np.where(self.kappa > 0, s, 0.0)

    @property
    def extended(self) -> bool:
        """True when the engine needs its extension arrays: a protected body or mass-in-mass beads."""
        return self.body or self.res_k is not None

    @property
    def n_contacts(self) -> int:
        """Number of real contacts: N + 1 with a wall, N without."""
        return self.n_beads + (1 if self.has_wall else 0)

    @property
    def general(self) -> bool:
        """True when the slower general force loop is needed (dissipation, offsets, a protected
        body or mass-in-mass beads)."""
        return self.law != 0 or self.misaligned or self.extended

    def yield_overlap(self) -> np.ndarray:
        """Overlap delta_y [m] at which every contact reaches its elastic limit, (N+1,).

        F_Y = kappa delta_y^(3/2) (:func:`hertzchain.contact.yield_force`, Thornton's F_y with
        p_y = 1.5 sigma_Y); times ``yield_pressure_ratio`` squared for another limiting pressure
        (delta_y ~ p_y^2); inf where no yield stress is given or there is no contact.
        """
        kap = self.kappa
        ok = (kap > 0) & np.isfinite(self.yield_force)
        with np.errstate(divide="ignore", invalid="ignore"):
            dy = np.where(ok, (self.yield_force / np.where(ok, kap, 1.0)) ** (2.0 / 3.0), np.inf)
        return dy if self.yield_pressure_ratio == 1.0 else dy * self.yield_pressure_ratio**2

    def _memo(self, key: str, compute):
        """``compute()`` once per System (a System's arrays are not changed after it is built: the
        engines pack copies): a run asks for :meth:`max_overlap` and :meth:`max_frequency` from
        the step plan, the pre-flight and the checks after it (4 and 3 times per simulate())."""
        memo = self.__dict__.get("_memo_values")
        if memo is None:
            memo = {}
            object.__setattr__(self, "_memo_values", memo)  # not a field: eq, repr and replace() ignore it
        if key not in memo:
            memo[key] = compute()
        return memo[key]

    def max_overlap(self) -> np.ndarray:
        """Upper bound of every contact's overlap [m] over the whole run, (N+1,) (a new array each
        call; computed once per System).

        All the energy available (striker kinetic energy + precompression energy) put into one
        contact: (2/5) kappa delta^(5/2) <= E, plus the static overlap d0. Contacts with kappa = 0
        (no wall) get 0. For the elastic-plastic law the energy goes along Thornton's loading
        curve (softer than Hertz past the yield overlap, so deeper), and the precompression
        energy counted is the work along it.
        """
        return self._memo("max_overlap", self._max_overlap).copy()

    def _max_overlap(self) -> np.ndarray:
        energy = 0.5 * self.mass[0] * self.v0[0] ** 2
        kap = self.kappa
        spec = law_of_code(self.law)
        if spec.generated:  # the law's own energy: delta with energy(delta) = E
            assert spec.energy is not None  # a generated law has all its functions (register_law)
            inv = spec.overlap_at_energy or (lambda e, k, p: overlap_at_energy(spec.energy, e, k, p))
            energy += float(np.sum([spec.energy(d, k, p) for d, k, p in zip(self.d0, kap, self.damping) if k > 0]))
            return np.array([inv(energy, k, p) if k > 0 else 0.0 for k, p in zip(kap, self.damping)]) + self.d0
        if spec.plastic:
            from .plasticity import thornton_loading_overlap, thornton_loading_work

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
        spec = law_of_code(self.law)
        if spec.generated:  # dF/d rate of the law at that overlap (at the state of first touch)
            assert spec.partials is not None  # a generated law has all its functions (register_law)
            return np.array([abs(spec.partials(max(d, 0.0), 0.0, k, p, 1.0)[1]) if k > 0 else 0.0
                             for d, k, p in zip(overlap, self.kappa, self.damping)])
        if not spec.dissipative:
            return np.zeros_like(self.kappa)
        if spec.calibrated == "gamma":
            return np.where(self.kappa > 0, self.damping, 0.0)
        if spec.calibrated == "A" or spec.plastic:
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
        dashpots: omega_max is taken as max_i sqrt(omega_i^2 + beta_i^2 / 4) + beta_i / 2. A
        protected body's mount is one more (linear) contact, and a mass-in-mass bead's internal
        spring k_in adds to its row (2 k_in / m) and gives its internal mass the row 2 k_in / m_in.
        """
        return self._memo("max_frequency", self._max_frequency)

    def _max_frequency(self) -> float:
        omega2, beta, inner = self.frequency_rows()
        w = float(np.max(np.sqrt(omega2 + 0.25 * beta**2) + 0.5 * beta))
        return max(w, float(np.max(inner))) if inner.size else w

    def frequency_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The Gershgorin rows of :meth:`max_frequency`, per moving body: the undamped bound omega_i^2
        [rad^2/s^2], the damping rate beta_i [1/s] (body i's bound is sqrt(omega_i^2 + beta_i^2 / 4) +
        beta_i / 2), and the internal masses' sqrt(2 k_in / m_in) [rad/s] per body (0 where none; an
        empty array without mass-in-mass beads). What sets the time step can be read from them
        (:func:`hertzchain.checks.check_step_count`).
        """
        dmax = self.max_overlap()
        k = 1.5 * self.kappa * np.sqrt(dmax)
        c = self.damping_coefficients(dmax)
        nb = self.n_moving
        if self.extended:  # the mount is contact N + 1, the internal springs add to their body's row
            k = np.append(k, self.mount_k)
            c = np.append(c, self.mount_c)
        kin = np.zeros(nb) if self.res_k is None else self.res_k[:nb]
        omega2 = 2.0 * (np.concatenate([[0.0], k[: nb - 1]]) + k[:nb] + kin) * self.inv_mass[:nb]
        beta = 2.0 * (np.concatenate([[0.0], c[: nb - 1]]) + c[:nb]) * self.inv_mass[:nb]
        inner = np.zeros(0)
        if self.res_k is not None:
            assert self.res_m is not None  # set together with res_k (bodies.extend)
            with np.errstate(divide="ignore", invalid="ignore"):
                inner = np.where(self.res_m[:nb] > 0, np.sqrt(2.0 * self.res_k[:nb] / self.res_m[:nb]), 0.0)
        return omega2, beta, inner


@dataclass(frozen=True)
class Model:
    """A chain hit by a striker, ended by a wall, with a contact law.

    Parameters
    ----------
    chain
        The beads.
    striker
        The impacting sphere (body 0); None: no striker (a crystal that a ``drive`` excites): no
        body 0 and contact 0, or a displacement drive's driver, a flat of bead 1's material.
    wall
        The end condition (default: immovable flat of the chain's material).
    law
        Contact law: :class:`Elastic` (paper eq. 1), :class:`Viscoelastic`, :class:`ScaledViscoelastic`,
        :class:`Dashpot`, :class:`ScaledDashpot` or :class:`Elastoplastic` (Thornton 1997).
    precompression
        Static force [N] squeezing beads 1..N against the wall before impact (0 = the paper's
        "barely touching" chain). Needs a wall.
    gravity
        Acceleration of gravity along the chain, towards the wall [m/s^2] (9.81 for a vertical
        column standing on the wall, bead 1 on top; g sin(tilt) on a track inclined by ``tilt``).
        Every body feels its weight m g; the run starts from the static equilibrium, the striker
        resting on bead 1 (see the conventions page). 0 (default): a horizontal chain.
    loads
        Static forces on chosen beads, ``((bead, force), ...)``: bead number 1..N and force [N]
        along the chain, > 0 towards the wall. The run starts from the static equilibrium
        (:func:`hertzchain.equilibrium`). Empty (default): none.
    drive
        A :class:`hertzchain.Drive` on bead 1 (a harmonic force or a prescribed displacement,
        see the granular-crystals guide); None (default): the striker's impact only.
    """

    chain: Chain
    striker: Striker | None = field(default_factory=Striker)
    wall: Wall = field(default_factory=Wall)
    #: any registered law's object (hertzchain.laws): these, PowerLaw, HuntCrossley, a user's
    law: LawObject = field(default_factory=Elastic)
    precompression: float = 0.0
    gravity: float = 0.0
    loads: tuple = ()
    drive: Drive | None = None

    def __post_init__(self) -> None:
        spec_of(self.law)  # a registered law (ConfigError naming contact.law otherwise)
        if self.striker is not None and not isinstance(self.striker, Striker):
            raise ConfigError("striker", f"must be a hertzchain.Striker or None (no striker), got {self.striker!r}")
        self._check_loads()
        self._check_drive()
        object.__setattr__(self, "precompression", real(self.precompression, "chain.precompression", unit="N"))
        if not (math.isfinite(self.precompression) and self.precompression >= 0):
            raise ConfigError("chain.precompression", f"must be a force >= 0 in N, got {self.precompression!r}")
        if self.chain.n_beads == 0 and (self.striker is None or not self.wall.present):
            raise ConfigError("chain.uniform.n", "a chain of zero beads needs a striker and a wall or a body for it to "
                              "hit (wall.type = 'none' leaves it flying)")
        if self.chain.n_beads == 0 and self.precompression > 0:
            raise ConfigError("chain.precompression", "a chain of zero beads has nothing to precompress")
        if self.precompression > 0 and not self.wall.present:
            raise ConfigError("chain.precompression", "a static precompression needs a wall to push against")
        if self.precompression > 0 and not self.chain.is_aligned:
            raise ConfigError("chain.precompression", "precompression together with bead offsets is not supported")
        # The striker's contact obeys the same head-on rule as the chain's (Chain checks beads n, n+1):
        # the striker flies along the axis, so bead 1's offset e_1 must stay below (R_s + R_1) / 2;
        # past R_s + R_1 it would miss the chain and the run would report 0 N.
        e1 = abs(float(np.asarray(self.chain.offsets)[0])) if self.chain.n_beads and self.striker is not None else 0.0
        if (e1 and self.striker is not None
                and e1 >= (reach := 0.5 * (self.striker.diameter / 2 + self.chain.radii[0]))):
            raise ConfigError("chain.offsets", f"bead 1 is offset by {e1:.3g} m from the striker's line of flight, "
                              f"more than half the sum of their radii ({reach:.3g} m); the striker would not "
                              "hit it head-on (or would miss the chain)")
        g = check_bound(self.gravity, "gravity", "chain.gravity", "m/s^2 (towards the wall)")
        object.__setattr__(self, "gravity", g)
        if g > 0 and not self.wall.present:
            raise ConfigError("chain.gravity", "a chain under gravity needs a wall (or a body) to stand on; "
                              "wall.type = 'none' would let it fall")
        if g > 0 and not self.chain.is_aligned:
            raise ConfigError("chain.gravity", "gravity together with bead offsets is not supported")
        if hasattr(self.law, "limiting_pressure_factor"):
            # a law with a limiting pressure (Thornton's) needs it at every contact; a material without
            # a yield stress would silently stay elastic (plastic work 0, yield_force NaN)
            used = [self.body0.material, *self.chain.materials] + ([self.wall_material] if self.wall.present else [])
            bare = next((m for m in used if m is not None and m.yield_stress is None), None)
            if bare is not None:
                raise ConfigError(f"materials.{bare.name}.yield_stress",
                                  f"material {bare.name!r} has no yield stress, which law {self.law.name!r} needs at "
                                  "every contact (its limiting pressure p_y = factor x sigma_Y): give it one in Pa "
                                  "under [materials.NAME], or use an elastic or viscoelastic law")
        if (g > 0 or self.precompression > 0) and self.wall.is_body and self.wall.stiffness == 0:
            raise ConfigError("wall.stiffness", "a free body (stiffness 0) cannot hold the chain's static load "
                              "(chain.gravity, chain.precompression): give its mount a stiffness in N/m")

    def _check_drive(self) -> None:
        """A drive is a :class:`hertzchain.Drive` (checked by its own constructor) that fits the model."""
        if self.drive is not None:
            from .crystal.drive import check_drive_fits

            check_drive_fits(self.drive, has_striker=self.striker is not None, has_wall=self.wall.present)

    @property
    def body0(self) -> Striker:
        """The striker, or without one a stand-in (bead 1's diameter and material, a flat face) for the
        arrays of body 0 and contact 0, which :mod:`hertzchain.bodies` then removes (or makes a driver's)."""
        if self.striker is not None:
            return self.striker
        return Striker(float(self.chain.diameters[0]), 1.0, self.chain.materials[0], shape="flat")

    def _check_loads(self) -> None:
        """Validate ``loads`` (:func:`hertzchain.bodies.checked_loads`) and store them as a tuple of pairs."""
        from .bodies import checked_loads

        object.__setattr__(self, "loads", checked_loads(self.loads, self.chain, self.wall))

    def __repr__(self) -> str:
        pre = f", precompression {self.precompression:.4g} N" if self.precompression else ""
        pre += f", gravity {self.gravity:.4g} m/s^2" if self.gravity else ""
        return f"Model({self.chain!r}, {self.striker!r}, {self.wall!r}, {self.law!r}{pre})"

    def _repr_html_(self) -> str:
        from .display import counts_text, diameters_text, html_table

        chain = self.chain
        rows = [("chain", diameters_text(chain.diameters)),
                ("materials", counts_text(m.name for m in chain.materials)),
                ("striker", repr(self.striker)[len("Striker("):-1]),
                ("wall", "free end" if (wall_material := self.wall_material) is None else
                 f"{'protected body' if self.wall.is_body else 'flat'}, {wall_material.name}"),
                ("contact law", repr(self.law))]
        if self.precompression:
            rows.append(("precompression", f"{self.precompression:.4g} N"))
        return html_table("Model", rows)

    @property
    def wall_material(self) -> Material | None:
        """Material of the wall's cap or the body's face: ``wall.material``, else the chain's first
        bead material (the base material: changing the beads near the wall does not change it);
        with zero beads, the striker's (a config passes ``chain.material``)."""
        if not self.wall.present:
            return None
        if self.wall.material is None and not self.chain.n_beads:  # no beads: the striker's (a config: the chain's)
            assert self.striker is not None  # zero beads need a striker (__post_init__)
            return self.striker.material
        return self.wall.material if isinstance(self.wall.material, Material) else self.chain.materials[0]

    @property
    def extended(self) -> bool:
        """True when the engine needs its extension (``System.extended``): a protected body or
        mass-in-mass beads."""
        return self.wall.is_body or any(el.resonator_fraction > 0 for el in self.chain.elements)

    @property
    def plain(self) -> bool:
        """True for the paper's kind of model (sphere striker, spheres, a flat wall or a free end, no
        gravity): its arrays are computed by the array set-up of ensembles too."""
        return (self.striker is not None and self.striker.plain and not self.wall.is_body and self.chain.plain and self.gravity == 0
                and not self.loads and self.drive is None)

    def system(self) -> System:
        """Flatten the model into SI arrays (see :class:`System`); built once per Model (a Model is
        immutable; the System's arrays are not changed by the engines, which pack copies)."""
        cached = self.__dict__.get("_system")
        if cached is None:
            cached = self._build_system()
            object.__setattr__(self, "_system", cached)  # not a field: eq, repr and replace() ignore it
        return cached

    def _build_system(self) -> System:
        n = self.chain.n_beads
        mass = np.empty(n + 2)
        mass[0] = self.body0.mass
        mass[1 : n + 1] = self.chain.masses
        mass[n + 1] = np.inf
        inv_mass = np.zeros(n + 2)
        inv_mass[: n + 1] = 1.0 / mass[: n + 1]

        # Hertz constants and elastic limits of every contact, vectorised over the chain (a Python
        # loop over contact_radii() took ~4 s for 1e6 beads): the formulas of contact.hertz_constant
        # and contact.yield_force, with bodies 0..N and the wall as body N + 1 (flat: 1/R' = 0).
        r = np.concatenate([[self.body0.diameter / 2], self.chain.radii])
        theta, sigma = material_columns([self.body0.material, *self.chain.materials])
        inv_r = 1.0 / r[:-1] + 1.0 / r[1:]
        t_sum = theta[:-1] + theta[1:]
        s_min = np.fmin(sigma[:-1], sigma[1:])  # weaker material; NaN = no yield stress given
        if (wall_material := self.wall_material) is not None:  # (exactly when the wall is present)
            wall_theta, wall_sigma = material_columns([wall_material])
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
        spec = spec_of(self.law)
        if hasattr(self.law, "contact_stiffness"):  # a law's own k (e.g. the power law's stiffness)
            kappa = self.law.contact_stiffness(kappa)
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
            if spec.generated:  # the overlap at which the law's static force is F0
                d0[1:] = [static_overlap(spec, self.precompression, k, p) for k, p in zip(kappa[1:], damping[1:])]
            if spec.plastic:
                # statically loaded along Thornton's loading curve: past F_y the line F_y + slope (d - dy)
                assert hasattr(self.law, "pressure_ratio")  # a plastic law's limiting pressure (Thornton's)
                f_y = fy[1:] * self.law.pressure_ratio**3
                with np.errstate(invalid="ignore"):
                    dy = (f_y / kappa[1:]) ** (2.0 / 3.0)
                    over = self.precompression > f_y
                    plastic = dy + (self.precompression - f_y) / (1.5 * kappa[1:] * np.sqrt(dy))
                d0[1:] = np.where(over, plastic, d0[1:])

        e = np.concatenate([[0.0], self.chain.offsets, [0.0]])
        de = np.diff(e)
        de[n] = 0.0  # a flat wall is unaffected by the last bead's offset (docs/conventions.rst)
        r = np.concatenate([[self.body0.diameter / 2], self.chain.radii, [0.0]])
        rsum = r[:-1] + r[1:]
        # Misaligned neighbours start touching along their line of centres (docs/conventions.rst).
        dx0 = np.sqrt(np.maximum(rsum**2 - de**2, 0.0))

        v0 = np.zeros(n + 2)
        v0[0] = self.body0.velocity
        parts = dict(mass=mass, inv_mass=inv_mass, kappa=kappa, damping=damping, d0=d0, de=de, dx0=dx0,
                     rsum=rsum, fext=fext, u0=np.zeros(n + 2), v0=v0, law=spec.code,
                     misaligned=bool(np.any(de != 0.0)), has_wall=self.wall.present, yield_force=fy,
                     yield_pressure_ratio=getattr(self.law, "pressure_ratio", 1.0))
        if self.plain:
            return System(**parts)
        from .bodies import extend  # the striker's face, elements, the protected body, gravity

        return System(**extend(self, parts))

    def describe_text(self) -> str:
        """``json.dumps(self.describe())`` (results' ``model`` attribute), built once per model as :meth:`system`."""
        if (text := self.__dict__.get("_describe_text")) is None:
            object.__setattr__(self, "_describe_text", text := json.dumps(self.describe()))  # not a field
        return text

    def describe(self) -> dict:
        """Plain-data description of the model (stored in result attributes)."""
        law: dict[str, Any] = {"law": self.law.name}
        law.update({p: getattr(self.law, p) for p in spec_of(self.law).param_names})  # as declared in laws/
        scaled: Any = self.law  # a size-scaled law (ScaledViscoelastic, ScaledDashpot) names its reference pair
        if getattr(scaled, "diameter", None) is not None:
            law.update(reference_diameter_mm=scaled.diameter * 1e3, reference_material=scaled.material.name)
        wall: dict[str, Any] = {"type": self.wall.kind,
                                "material": None if self.wall_material is None else self.wall_material.name}
        if self.wall.is_body:
            wall.update(mass=self.wall.mass, stiffness=self.wall.stiffness, damping=self.wall.damping,
                        shape=self.wall.shape, radius_of_curvature_mm=None if self.wall.face_radius is None
                        else self.wall.face_radius * 1e3)
        out = {
            "chain": self.chain.describe(),
            "striker": None if self.striker is None else self.striker.describe(),
            "wall": wall,
            "contact": law,
            "precompression": self.precompression,
        }
        if self.gravity:
            out["gravity"] = self.gravity
        if self.loads:
            out["load"] = {"beads": [b for b, _ in self.loads], "forces": [f for _, f in self.loads]}
        if self.drive is not None:
            out["drive"] = self.drive.describe()
        return out

