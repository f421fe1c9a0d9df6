"""Chains of beads: diameters, materials and perpendicular offsets, with the paper's builders.

Numbering follows docs/conventions.rst: beads 1..N from the impact end; in arrays bead n sits at
index n - 1. Masses are m = rho pi phi^3 / 6.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike

from .elements import SPHERE, Element
from .errors import ConfigError
from .materials import Material, get_material
from .strict import count, real, real_array

__all__ = ["Chain", "TABLE_I_MM", "paper_chain"]

#: Bead diameters [mm] of the paper's Table I (beads 1-16 are the 26 mm monodisperse part).
TABLE_I_MM: dict[str, tuple[float, ...]] = {
    "chain1": (26.0,) * 16 + (24.00, 23.00, 22.00, 21.00, 20.00, 19.00, 18.00, 16.65, 16.00, 15.00,
                               14.00, 13.00, 12.00, 11.00),
    "chain2": (26.0,) * 16 + (24.00, 22.00, 20.00, 18.00, 16.65, 16.00, 14.00, 13.00, 12.00, 11.00,
                               10.00, 9.00),
}


def _check_diameters(diameters: np.ndarray, field_name: str) -> None:
    if diameters.ndim != 1:
        raise ConfigError(field_name, "must be a list of diameters")
    bad = np.flatnonzero(~np.isfinite(diameters) | (diameters <= 0))
    if bad.size:
        i = int(bad[0])
        raise ConfigError(f"{field_name}[{i}]", f"diameter of bead {i + 1} must be a positive finite number, "
                          f"got {diameters[i]!r}")


@dataclass(frozen=True, eq=False)
class Chain:
    """A line of spherical beads, numbered 1..N from the impact end.

    Parameters
    ----------
    diameters
        Bead diameters phi_n [m], shape (N,).
    materials
        One :class:`Material` per bead (a single material or name is broadcast).
    offsets
        Perpendicular offsets e_n of the bead centres from the chain axis [m], shape (N,);
        zeros for an aligned chain (see the conventions page, misalignment).
    elements
        One :class:`~hertzchain.elements.Element` per bead (a single one is broadcast): what
        each bead is (sphere, cylinder, given mass, mass-in-mass); plain spheres when empty.
    """

    diameters: np.ndarray
    materials: tuple[Material, ...] = field(default=())
    offsets: np.ndarray | None = None
    elements: tuple[Element, ...] = field(default=())

    def __post_init__(self) -> None:
        # Chains are built by the thousand in a design search (every geometry check builds one):
        # the checks below take their slow, index-finding path only when something is wrong.
        raw = self.diameters
        # Numbers only (a string or a bool is refused, as in a config file), copied as floats.
        d = np.array(raw, dtype=float) if isinstance(raw, np.ndarray) and raw.dtype.kind in "iuf" else \
            real_array(raw, "chain.diameters")
        # Zero beads is a chain too: the striker hits the wall (or body) directly, the reference
        # that says what a chain buys (contact 0 is then striker-wall).
        if d.ndim != 1 or (d.size and not (d.min() > 0 and d.max() < math.inf)):  # NaN fails both
            _check_diameters(d, "chain.diameters")
        d.setflags(write=False)
        object.__setattr__(self, "diameters", d)
        mats = self.materials
        if isinstance(mats, (str, Material)):
            mats = (get_material(mats),) * d.size
        elif len(mats) == 0:
            mats = (get_material("AISI52100"),) * d.size
        elif not (isinstance(mats, tuple) and all(type(m) is Material for m in mats)):
            mats = tuple(get_material(m) for m in mats)
        if len(mats) != d.size:
            raise ConfigError("chain.materials", f"needs one material per bead ({d.size}), got {len(mats)}")
        object.__setattr__(self, "materials", mats)
        els = self.elements
        if isinstance(els, Element):
            els = (els,) * d.size
        elif len(els) == 0:
            els = (SPHERE,) * d.size
        else:
            els = tuple(els)
            if len(els) != d.size:
                raise ConfigError("chain.elements", f"needs one element per bead ({d.size}), got {len(els)}")
            if not all(type(x) is Element for x in els):
                raise ConfigError("chain.elements", "every entry must be a hertzchain Element")
        object.__setattr__(self, "elements", els)
        if self.offsets is None:  # aligned: nothing to check
            e = np.zeros(d.size)
            e.setflags(write=False)
            object.__setattr__(self, "offsets", e)
            return
        e = real_array(self.offsets, "chain.offsets")
        if e.shape != d.shape:
            raise ConfigError("chain.offsets", f"needs one offset per bead ({d.size}), got {e.size}")
        if not np.all(np.isfinite(e)):
            raise ConfigError("chain.offsets", "offsets must be finite")
        radii = d / 2
        # Neighbours must still overlap along the axis: |e_n - e_{n+1}| < R_n + R_{n+1}.
        de = np.abs(np.diff(e))
        too_far = np.flatnonzero(de >= 0.5 * (radii[:-1] + radii[1:]))
        if too_far.size:
            n = int(too_far[0]) + 1
            raise ConfigError("chain.offsets", f"beads {n} and {n + 1} are offset by {de[n - 1]:.3g} m, more than half "
                              "the sum of their radii; the contact would not be a head-on Hertz contact")
        if e.any() and not self.plain:
            raise ConfigError("chain.offsets", "offsets are modelled for spheres only; a chain with cylinders or "
                              "mass-in-mass beads must stay aligned")
        e.setflags(write=False)
        object.__setattr__(self, "offsets", e)

    # ---------------------------------------------------------------- builders
    @classmethod
    def from_diameters(cls, diameters: ArrayLike, material: str | Material | Sequence = "AISI52100",
                       offsets: ArrayLike | None = None) -> "Chain":
        """Chain from explicit diameters [m] (one material for all beads, or one per bead)."""
        d = real_array(diameters, "chain.diameters")
        # a name or a Material is broadcast to every bead by __post_init__
        mats: Any = material if isinstance(material, (str, Material)) else tuple(material)
        return cls(d, mats, None if offsets is None else real_array(offsets, "chain.offsets"))

    @classmethod
    def uniform(cls, n: int, diameter: float, material: str | Material = "AISI52100") -> "Chain":
        """``n`` identical beads of diameter ``diameter`` [m] (``n`` an int: 2.7 beads is refused)."""
        n = count(n, "chain.n", low=0)  # 0: no chain, the striker hits the wall
        return cls.from_diameters([real(diameter, "chain.diameter", unit="m")] * n, material)

    def append_taper(self, n: int, q: float, material: str | Material | None = None) -> "Chain":
        """Append ``n`` beads with the exponential taper phi_{k+1} = (1 - q) phi_k (paper Sec. II).

        The first appended bead is (1 - q) times the current last bead. ``q`` is a fraction
        (0.056 for 5.6 %); it must be in [0, 1).
        """
        n = count(n, "chain.taper.n", low=0)
        q = real(q, "chain.taper.q")
        if not (0.0 <= q < 1.0):
            raise ConfigError("chain.taper.q", f"tapering factor must lie in [0, 1), got {q!r}")
        last = self.diameters[-1]
        new = last * (1.0 - q) ** np.arange(1, int(n) + 1)
        mat = get_material(material) if material is not None else self.materials[-1]
        # One Chain built (not a tapered one and then the concatenation): geometry checks of a
        # design search build thousands.
        assert self.offsets is not None  # __post_init__ sets it (zeros when aligned)
        aligned = not self.offsets.any()
        return Chain(np.concatenate([self.diameters, new]), self.materials + (mat,) * int(n),
                     None if aligned else np.concatenate([self.offsets, np.zeros(int(n))]),
                     self.elements + (SPHERE,) * int(n))

    def concat(self, other: "Chain") -> "Chain":
        """Beads of ``self`` followed by the beads of ``other``."""
        assert self.offsets is not None and other.offsets is not None  # __post_init__ sets them
        aligned = not (self.offsets.any() or other.offsets.any())
        return Chain(np.concatenate([self.diameters, other.diameters]), self.materials + other.materials,
                     None if aligned else np.concatenate([self.offsets, other.offsets]),
                     self.elements + other.elements)

    def truncated(self, n: int) -> "Chain":
        """The first ``n`` beads (the paper's protocol: a chain cut after bead n, wall behind it)."""
        n = count(n, "chain.truncate")
        if not (1 <= n <= self.n_beads):
            raise ConfigError("chain.truncate", f"must be between 1 and {self.n_beads}, got {n}")
        assert self.offsets is not None  # __post_init__ sets it
        return Chain(self.diameters[:n], self.materials[:n], self.offsets[:n], self.elements[:n])

    def substitute(self, bead: int, diameter: float | None = None,
                   material: str | Material | None = None, element: Element | None = None) -> "Chain":
        """Replace bead ``bead`` (1-based) by one of another diameter [m], material and/or element."""
        if not (1 <= bead <= self.n_beads):
            raise ConfigError("chain.substitutions.bead", f"bead must be between 1 and {self.n_beads}, got {bead}")
        d = self.diameters.copy()
        mats = list(self.materials)
        if diameter is not None:
            d[bead - 1] = diameter
        if material is not None:
            mats[bead - 1] = get_material(material)
        els = self.elements
        if element is not None:
            els = els[:bead - 1] + (element,) + els[bead:]
        return Chain(d, tuple(mats), self.offsets, els)

    def with_offsets(self, offsets: ArrayLike | dict[int, float]) -> "Chain":
        """Same beads with perpendicular offsets [m]: a full list, or {bead: offset} (1-based)."""
        if isinstance(offsets, dict):
            assert self.offsets is not None  # __post_init__ sets it
            e = self.offsets.copy()
            for bead, value in offsets.items():
                if not (1 <= int(bead) <= self.n_beads):
                    raise ConfigError("chain.offsets", f"bead {bead} is not in 1..{self.n_beads}")
                e[int(bead) - 1] = value
        else:
            e = np.asarray(offsets, dtype=float)
        return replace(self, offsets=e)

    # ---------------------------------------------------------------- properties
    @property
    def n_beads(self) -> int:
        return int(self.diameters.size)

    def __len__(self) -> int:
        return self.n_beads

    @property
    def radii(self) -> np.ndarray:
        """Bead radii R_n [m]."""
        return self.diameters / 2.0

    @property
    def densities(self) -> np.ndarray:
        return np.array([m.density for m in self.materials])

    @property
    def plain(self) -> bool:
        """True when every bead is a plain sphere (no cylinder, given mass or resonator)."""
        return all(x.plain for x in self.elements)

    @property
    def masses(self) -> np.ndarray:
        """Bead masses [kg]: m_n = rho pi phi^3 / 6 for spheres; a cylinder's rho pi phi^2 L / 4, a
        given mass, the whole of a mass-in-mass bead (shell and internal mass) otherwise."""
        if not self.plain:
            return np.array([el.total_mass(float(dia), mat)
                             for el, dia, mat in zip(self.elements, self.diameters, self.materials)])
        mats = self.materials
        if not mats:  # no beads
            return np.zeros(0)
        # One material (the usual chain): its density as a scalar, the same numbers without a
        # per-bead array (a design search takes the mass of thousands of candidate chains).
        rho = mats[0].density if all(m is mats[0] for m in mats) else self.densities
        return rho * math.pi * self.diameters**3 / 6.0

    @property
    def is_aligned(self) -> bool:
        return not np.any(self.offsets)

    def __repr__(self) -> str:
        # One line: the diameters grouped in runs and the materials counted (not 30 full Materials).
        from .display import counts_text, diameters_text

        if not self.n_beads:
            return "Chain(no beads: the striker hits the wall)"
        text = f"Chain({diameters_text(self.diameters)}; {counts_text(m.name for m in self.materials)}"
        if not self.is_aligned:
            assert self.offsets is not None  # __post_init__ sets it
            text += f"; offsets up to {np.abs(self.offsets).max() * 1e3:.3g} mm"
        return text + ")"

    def _repr_html_(self) -> str:
        from .display import counts_text, diameters_text, html_table

        rows = [("beads", str(self.n_beads)), ("diameters", diameters_text(self.diameters).split(": ", 1)[1]),
                ("materials", counts_text(m.name for m in self.materials)),
                ("mass", f"{self.masses.sum() * 1e3:.4g} g"),
                ("length", f"{self.diameters.sum() * 1e3:.4g} mm"),
                ("offsets", "aligned" if self.is_aligned else
                 f"up to {np.abs(np.asarray(self.offsets)).max() * 1e3:.3g} mm")]
        return html_table("Chain", rows)

    def describe(self) -> dict:
        """Plain-data description (stored in result attributes)."""
        names = [m.name for m in self.materials]
        out: dict[str, Any] = {
            "diameters_mm": [float(x) for x in self.diameters * 1e3],
            "materials": names[0] if len(set(names)) == 1 else names,
            "offsets_mm": [float(x) for x in np.asarray(self.offsets) * 1e3],
        }
        if not self.plain:
            out["elements"] = [x.describe() for x in self.elements]
        return out


def paper_chain(name: str, material: str | Material = "AISI52100") -> Chain:
    """The paper's Table I chains by name: ``"chain1"`` (q ~ 5.60 %) or ``"chain2"`` (q ~ 8.27 %).

    Parameters
    ----------
    name : str
        ``"chain1"`` (30 beads, 26 mm down to 11 mm) or ``"chain2"`` (28 beads, 26 mm down to 9 mm).
    material : str or Material
        Material of every bead (default: the paper's AISI 52100 steel).

    Returns
    -------
    Chain
        The beads 1..N from the impact end, diameters in m (:data:`TABLE_I_MM` divided by 1000).
    """
    key = name.lower().replace("_", "").replace(" ", "")
    if key not in TABLE_I_MM:
        raise ConfigError("chain.preset", f"unknown paper chain {name!r}; known: {', '.join(TABLE_I_MM)}")
    return Chain.from_diameters(np.array(TABLE_I_MM[key]) * 1e-3, material)
