"""What the explorer shows, as plain values, and the run config that reproduces it.

The explorer's controls edit an :class:`ExplorerSettings`; everything it draws comes from the run
config of :meth:`ExplorerSettings.config` (validated by the one config schema,
:func:`hertzchain.parse_config`, and simulated as ``hertzchain run`` simulates a file), so
"save as config" writes exactly the run on the screen.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ..errors import ConfigError

__all__ = ["CHAIN_KINDS", "LAWS", "EPS_LAWS", "ExplorerSettings"]

#: The chain controls: the paper's two chains (Table I), a uniform block with an optional taper,
#: or the diameters bead by bead.
CHAIN_KINDS = {"paper chain 1 (Table I, q = 5.60 %)": "chain1", "paper chain 2 (Table I, q = 8.27 %)": "chain2",
               "uniform block + taper": "uniform", "per-bead diameters": "diameters"}
#: Contact laws offered (``[contact] law``); the dissipative ones are calibrated to the per-bead factor eps.
LAWS = {"elastic (Hertz, paper eq. 1)": "elastic", "Kuwabara-Kono, calibrated to eps": "viscoelastic",
        "dashpot, calibrated to eps": "dashpot", "elastoplastic (Thornton): yields above F_Y": "elastoplastic"}
#: The laws calibrated to the per-bead factor eps (the others take none).
EPS_LAWS = ("viscoelastic", "dashpot")


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
    striker_diameter_mm, striker_velocity : float
        Striker diameter [mm] and impact speed [m/s].
    wall : str
        ``"flat"`` (an immovable flat, the paper's sensor cap) or ``"none"`` (a free end).
    law : str
        ``"elastic"``, ``"viscoelastic"`` (Kuwabara-Kono), ``"dashpot"`` or ``"elastoplastic"``
        (Thornton: the contact yields above the materials' elastic limit F_Y).
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
    striker_diameter_mm: float = 8.0
    striker_velocity: float = 0.2
    striker_material: str = "AISI52100"
    wall: str = "flat"
    wall_material: str = "AISI52100"
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

        Returns
        -------
        dict
            Sections ``chain``, ``striker``, ``wall``, ``contact``, ``run``; valid for
            :func:`hertzchain.parse_config` when the values are (checked there, with errors
            naming the config field).
        """
        if self.chain in ("chain1", "chain2"):
            chain: dict = {"preset": self.chain}
        elif self.chain == "uniform":
            chain = {"uniform": {"n": int(self.uniform_n), "diameter_mm": float(self.uniform_diameter_mm)}}
            if self.taper_n > 0:
                chain["taper"] = {"n": int(self.taper_n), "q": float(self.taper_q)}
        elif self.chain == "diameters":
            chain = {"diameters_mm": _diameters(self.diameters_mm)}
        else:
            raise ConfigError("chain", f"unknown chain kind {self.chain!r}; choose from {', '.join(CHAIN_KINDS.values())}")
        chain["material"] = self.material
        if self.bead_materials.strip():
            chain["materials"] = _materials(self.bead_materials)
        contact: dict = {"law": self.law}
        if self.law in EPS_LAWS:
            contact["eps"] = float(self.eps)
        return {
            "chain": chain,
            "striker": {"diameter_mm": float(self.striker_diameter_mm), "velocity": float(self.striker_velocity),
                        "material": self.striker_material},
            "wall": {"type": self.wall, **({"material": self.wall_material} if self.wall == "flat" else {})},
            "contact": contact,
            "run": {"duration": "auto", "sample_interval": float(self.sample_interval)},
        }

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
