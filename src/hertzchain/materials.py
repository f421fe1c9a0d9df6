"""Elastic materials of beads, strikers and wall caps.

All values in SI: density [kg/m^3], Young's modulus [Pa], Poisson ratio [-], yield stress [Pa].

Sources of the catalogue
------------------------
- ``AISI52100`` (hardened chrome bearing steel, the paper's beads): rho = 7780 kg/m^3,
  Y = 203 +- 4 GPa, nu = 0.3, sigma_Y ~ 2 GPa, as given in Melo et al., PRE 2006, Sec. II.
- ``stainless_steel`` (AISI 304, annealed): rho = 8000 kg/m^3, Y = 193 GPa, nu = 0.29,
  sigma_Y = 215 MPa (ASM Handbook vol. 1, 304 annealed sheet/bar values).
- ``brass`` (cartridge brass C26000): rho = 8530 kg/m^3, Y = 110 GPa, nu = 0.35,
  sigma_Y = 200 MPa (ASM Handbook vol. 2, half-hard 260 brass gives 200-360 MPa).
- ``aluminium`` (6061-T6): rho = 2700 kg/m^3, Y = 68.9 GPa, nu = 0.33, sigma_Y = 276 MPa
  (ASM Handbook vol. 2 / Aluminum Association data).
- ``glass`` (soda-lime): rho = 2500 kg/m^3, Y = 72 GPa, nu = 0.22; brittle, no plastic yield,
  so ``yield_stress`` is None and no elastic-limit check is made (handbook values).
- ``PTFE``: rho = 2200 kg/m^3, Y = 1.46 GPa, nu = 0.46, sigma_Y ~ 10 MPa (values used for PTFE
  beads in Daraio et al., PRE 73, 026610 (2006); yield from DuPont Teflon data sheets).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .bounds import check_bound
from .errors import ConfigError

__all__ = ["Material", "CATALOGUE", "get_material", "register_material"]


@dataclass(frozen=True)
class Material:
    """An isotropic linear-elastic material.

    Parameters
    ----------
    name
        Catalogue or user name.
    density
        Mass density rho [kg/m^3].
    young
        Young's modulus Y [Pa].
    poisson
        Poisson ratio nu [-], -1 < nu < 0.5.
    yield_stress
        Yield stress sigma_Y [Pa] used for the paper's elastic-limit estimate, or None when the
        material has no meaningful plastic yield (brittle glass).
    source
        Where the numbers come from.
    """

    name: str
    density: float
    young: float
    poisson: float
    yield_stress: float | None = None
    source: str = field(default="user", compare=False)

    def __repr__(self) -> str:
        sy = "" if self.yield_stress is None else f", sigma_Y {self.yield_stress / 1e9:.4g} GPa"
        return (f"Material({self.name!r}: rho {self.density:.5g} kg/m^3, Y {self.young / 1e9:.4g} GPa, "
                f"nu {self.poisson:.3g}{sy})")

    def __post_init__(self) -> None:
        # the config's bounds (hertzchain.bounds): masses, stiffnesses and yield overlaps stay representable
        check_bound(self.density, "density", f"materials.{self.name}.density", "kg/m^3")
        check_bound(self.young, "young", f"materials.{self.name}.young", "Pa")
        if not (-1.0 < self.poisson < 0.5):
            raise ConfigError(f"material {self.name!r}.poisson", f"must lie in (-1, 0.5), got {self.poisson!r}")
        check_bound(self.yield_stress, "yield_stress", f"materials.{self.name}.yield_stress", "Pa", allow_none=True)

    @property
    def theta(self) -> float:
        """Elastic compliance theta = 3 (1 - nu^2) / (4 Y) [1/Pa] (paper Sec. III, after eq. 1)."""
        return 3.0 * (1.0 - self.poisson**2) / (4.0 * self.young)

    @property
    def reduced_modulus(self) -> float:
        """Plane-strain modulus Y / (1 - nu^2) [Pa]."""
        return self.young / (1.0 - self.poisson**2)


#: The material catalogue, name -> :class:`Material` (SI units: density [kg/m^3], Young's modulus
#: [Pa], Poisson ratio, yield stress [Pa]), each with its source; ``hertzchain materials`` lists it.
CATALOGUE: dict[str, Material] = {
    m.name: m
    for m in (
        Material("AISI52100", 7780.0, 203e9, 0.30, 2.0e9, "Melo et al. PRE 2006, Sec. II"),
        Material("stainless_steel", 8000.0, 193e9, 0.29, 215e6, "ASM Handbook, AISI 304 annealed"),
        Material("brass", 8530.0, 110e9, 0.35, 200e6, "ASM Handbook, C26000 half hard"),
        Material("aluminium", 2700.0, 68.9e9, 0.33, 276e6, "ASM Handbook, 6061-T6"),
        Material("glass", 2500.0, 72e9, 0.22, None, "handbook soda-lime glass (brittle)"),
        Material("PTFE", 2200.0, 1.46e9, 0.46, 10e6, "Daraio et al. PRE 73, 026610 (2006)"),
    )
}

_ALIASES = {"steel": "AISI52100", "52100": "AISI52100", "chrome_steel": "AISI52100",
            "aluminum": "aluminium", "teflon": "PTFE", "ss304": "stainless_steel"}


def register_material(material: Material) -> None:
    """Add a user material to the catalogue so that it can be named in configs.

    Parameters
    ----------
    material : Material
        The material (density [kg/m^3], Young's modulus [Pa], Poisson ratio, yield stress [Pa]);
        its ``name`` becomes usable wherever a material is named. A same-named entry is replaced.
    """
    CATALOGUE[material.name] = material


def get_material(material: str | Material) -> Material:
    """Return a :class:`Material` from a catalogue name (case-insensitive) or pass one through.

    Parameters
    ----------
    material : str or Material
        A catalogue name (``"AISI52100"``, aliases such as ``"steel"``) or a :class:`Material`.

    Returns
    -------
    Material
        The catalogue entry (SI units) or ``material`` itself.
    """
    if isinstance(material, Material):
        return material
    if not isinstance(material, str):
        raise ConfigError("material", f"must be a name or a Material, got {type(material).__name__}")
    key = _ALIASES.get(material.lower(), material)
    for name, mat in CATALOGUE.items():
        if name.lower() == key.lower():
            return mat
    raise ConfigError("material", f"unknown material {material!r}; known: {', '.join(sorted(CATALOGUE))} "
                      "(or define one under [materials.NAME] with density, young, poisson, yield_stress)")


def material_columns(materials: list[Material]) -> tuple[np.ndarray, np.ndarray]:
    """Per-body compliance theta [1/Pa] and yield stress [Pa] (NaN when not given) of ``materials``,
    each distinct Material read once (a chain of a million beads holds a few)."""
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
