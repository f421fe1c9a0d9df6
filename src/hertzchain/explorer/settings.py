"""What the explorer shows, as plain values, and the run config that reproduces it.

The explorer's controls edit an :class:`ExplorerSettings`; everything it draws comes from the run
config of :meth:`ExplorerSettings.config` (validated by the one config schema,
:func:`hertzchain.parse_config`, and simulated as ``hertzchain run`` simulates a file), so
"save as config" writes exactly the run on the screen.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ..bodies import MAX_BODY_DURATION, mount_half_period
from ..errors import ConfigError

__all__ = ["CHAIN_KINDS", "LAWS", "EPS_LAWS", "WALLS", "STRIKER_SHAPES", "MAX_BODY_DURATION", "ExplorerSettings",
           "mount_half_period"]

#: The chain controls: the paper's two chains (Table I), a uniform block with an optional taper,
#: or the diameters bead by bead.
CHAIN_KINDS = {"paper chain 1 (Table I, q = 5.60 %)": "chain1", "paper chain 2 (Table I, q = 8.27 %)": "chain2",
               "uniform block + taper": "uniform", "per-bead diameters": "diameters"}
#: Contact laws offered (``[contact] law``); the dissipative ones are calibrated to the per-bead factor eps.
LAWS = {"elastic (Hertz, paper eq. 1)": "elastic", "Kuwabara-Kono, calibrated to eps": "viscoelastic",
        "dashpot, calibrated to eps": "dashpot",
        "size-scaled dashpot, calibrated to eps (the reproduction's)": "dashpot_scaled",
        "elastoplastic (Thornton): yields above F_Y": "elastoplastic"}
#: The laws calibrated to the per-bead factor eps (the others take none).
EPS_LAWS = ("viscoelastic", "dashpot", "dashpot_scaled")
#: What ends the chain (``[wall] type``).
WALLS = {"flat wall (the paper's sensor cap)": "flat", "protected body (mass on a mount)": "body",
         "free end": "none"}
#: The striker's face (``[striker] shape``).
STRIKER_SHAPES = {"sphere": "sphere", "flat face": "flat"}


def _diameters(text: str) -> list[float]:
    """'26, 26, 24.5' (mm, commas or spaces) -> [26.0, 26.0, 24.5]."""
    parts = text.replace(",", " ").split()
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise ConfigError("chain.diameters_mm", f"{text!r} is not a list of numbers in mm, e.g. 26, 26, 24, 23") from None
    if not values:
        raise ConfigError("chain.diameters_mm", "give at least one diameter in mm, e.g. 26, 26, 24, 23")
    return values


def _number(value, field: str, unit: str) -> float:
    """A number box's value as a float; an emptied box (None) refused naming its config field."""
    if value is None:
        raise ConfigError(field, f"the box is empty: type a number in {unit}")
    return float(value)


def _materials(text: str) -> list[str]:
    """'AISI52100 x 28, brass x 2' (or names one by one, commas or spaces) -> one name per bead."""
    out: list[str] = []
    for part in text.split(","):
        words = part.split()
        if len(words) == 3 and words[1] == "x" and words[2].isdigit():
            out += [words[0]] * int(words[2])
        else:
            out += words
    return out


@dataclass(frozen=True)
class ExplorerSettings:
    """One view of the explorer (units in the names; the rest SI).

    Attributes
    ----------
    chain : str
        ``"chain1"``, ``"chain2"`` (the paper's Table I), ``"uniform"`` (``uniform_n`` beads of
        ``uniform_diameter_mm``, then ``taper_n`` beads shrinking by ``taper_q``) or
        ``"diameters"`` (``diameters_mm``, from the impact end).
    uniform_n, uniform_diameter_mm, taper_n, taper_q : int, float, int, float
        The uniform block [beads, mm] and the taper [beads, fraction: phi_(n+1) = (1 - q) phi_n].
    diameters_mm : str
        Bead diameters [mm], comma or space separated.
    material, striker_material, wall_material : str
        Catalogue names (``hertzchain materials``) of the beads, the striker and the wall.
    bead_materials : str
        One material per bead from the impact end, overriding ``material`` when not empty:
        names, commas or spaces, ``NAME x N`` for N beads in a row (``AISI52100 x 28, brass x 2``).
    gravity : float
        Acceleration of gravity along the chain, towards the wall [m/s^2] (``[chain] gravity``;
        0: a horizontal chain, 9.81: a column standing on the wall).
    striker_diameter_mm, striker_velocity : float
        Striker diameter [mm] and impact speed [m/s].
    striker_mass : float or None
        A given striker mass [kg] (``[striker] mass``: a drop hammer); None: the sphere's
        rho pi phi^3 / 6.
    striker_shape : str
        The striker's face: ``"sphere"`` or ``"flat"`` (a sphere-flat contact with bead 1).
    wall : str
        ``"flat"`` (an immovable flat, the paper's sensor cap), ``"body"`` (a protected body of
        ``body_mass`` on a mount of ``body_stiffness`` and ``body_damping`` to the ground) or
        ``"none"`` (a free end).
    body_mass, body_stiffness, body_damping : float
        The protected body: mass [kg], its mount's stiffness [N/m] (0: a free body) and dashpot
        [N s/m] (``[wall] mass``, ``stiffness``, ``damping``).
    law : str
        ``"elastic"``, ``"viscoelastic"`` (Kuwabara-Kono), ``"dashpot"``, ``"dashpot_scaled"``
        (the size-scaled dashpot, the reproduction's law) or ``"elastoplastic"`` (Thornton: the
        contact yields above the materials' elastic limit F_Y).
    eps : float
        Per-bead factor of the paper (Sec. III) the viscoelastic and dashpot laws are calibrated to.
    sample_interval : float
        Recording interval [s].
    """

    chain: str = "chain1"
    uniform_n: int = 16
    uniform_diameter_mm: float = 26.0
    taper_n: int = 14
    taper_q: float = 0.056
    diameters_mm: str = "26, 26, 26, 26, 26, 26, 26, 26, 24, 23, 22, 21, 20"
    material: str = "AISI52100"
    bead_materials: str = ""
    gravity: float = 0.0
    striker_diameter_mm: float = 8.0
    striker_velocity: float = 0.2
    striker_material: str = "AISI52100"
    striker_mass: float | None = None
    striker_shape: str = "sphere"
    wall: str = "flat"
    wall_material: str = "AISI52100"
    body_mass: float = 1.0
    body_stiffness: float = 1.0e6
    body_damping: float = 0.0
    law: str = "elastic"
    eps: float = 0.985
    sample_interval: float = 5e-7

    def replace(self, **changes) -> "ExplorerSettings":
        """A copy with ``changes``.

        Parameters
        ----------
        **changes
            Field values to change.

        Returns
        -------
        ExplorerSettings
            The new settings.
        """
        return dataclasses.replace(self, **changes)

    def config(self) -> dict:
        """The run config (a TOML mapping) of this view.

        The bead velocities are recorded (``[probes] velocities``): the theory table measures the
        per-bead velocity ratio of paper eq. 6 on them. The duration is the automatic one
        (:func:`hertzchain.auto_duration`), which runs past the pulse by half a protected body's
        mount period (:func:`~hertzchain.bodies.mount_half_period`, at most to
        :data:`~hertzchain.bodies.MAX_BODY_DURATION`): the mount's force peaks as the body swings.

        Returns
        -------
        dict
            Sections ``chain``, ``striker``, ``wall``, ``contact``, ``run``, ``probes``; valid for
            :func:`hertzchain.parse_config` when the values are (checked there, with errors
            naming the config field).
        """
        if self.chain in ("chain1", "chain2"):
            chain: dict = {"preset": self.chain}
        elif self.chain == "uniform":
            chain = {"uniform": {"n": int(self.uniform_n),
                                 "diameter_mm": _number(self.uniform_diameter_mm, "chain.uniform.diameter_mm", "mm")}}
            if self.taper_n > 0:
                chain["taper"] = {"n": int(self.taper_n), "q": float(self.taper_q)}
        elif self.chain == "diameters":
            chain = {"diameters_mm": _diameters(self.diameters_mm)}
        else:
            raise ConfigError("chain", f"unknown chain kind {self.chain!r}; choose from {', '.join(CHAIN_KINDS.values())}")
        chain["material"] = self.material
        if self.bead_materials.strip():
            chain["materials"] = _materials(self.bead_materials)
        if self.gravity:  # absent (or an emptied box) is a horizontal chain (0), which also runs without a wall
            chain["gravity"] = float(self.gravity)
        striker: dict = {"diameter_mm": _number(self.striker_diameter_mm, "striker.diameter_mm", "mm"),
                         "velocity": _number(self.striker_velocity, "striker.velocity", "m/s"),
                         "material": self.striker_material, "shape": self.striker_shape}
        if self.striker_mass is not None:
            striker["mass"] = float(self.striker_mass)
        wall: dict = {"type": self.wall}
        if self.wall in ("flat", "body"):
            wall["material"] = self.wall_material
        if self.wall == "body":
            for key, value, unit in (("mass", self.body_mass, "kg"), ("stiffness", self.body_stiffness, "N/m"),
                                     ("damping", self.body_damping, "N s/m")):
                wall[key] = _number(value, f"wall.{key}", unit)
        contact: dict = {"law": self.law}
        if self.law in EPS_LAWS:
            contact["eps"] = float(self.eps)
        config = {"chain": chain, "striker": striker, "wall": wall, "contact": contact,
                  "run": {"duration": "auto", "sample_interval": float(self.sample_interval)},
                  "probes": {"velocities": True}}
        return config

    def toml(self) -> str:
        """The run config as a TOML file that ``hertzchain run`` reproduces the view from.

        Returns
        -------
        str
            The file's text, with a header line saying where it came from.
        """
        import tomli_w

        return ("# Written by hertzchain explore: `hertzchain run THIS.toml --out result.nc` reproduces the view.\n"
                + tomli_w.dumps(self.config()))
