"""Members of one end and contact law kind but any numbers of beads: a design's generation.

A design search's generation holds chains of many lengths. As a :class:`Ragged` set (built by
:func:`ragged`) they are (member, bead) arrays padded to the longest chain, so that one
:func:`hertzchain.integrate.batch.systems.systems` call sets up the whole generation instead of one
call per bead count (an :class:`~hertzchain.integrate.batch.ensemble.Ensemble` has one).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...errors import ConfigError
from ...materials import Material
from ...model import Model
from .ensemble import layout_key

__all__ = ["Ragged", "ragged"]


@dataclass(frozen=True)
class Ragged:
    """Members of one end and contact law kind but any numbers of beads, as
    :func:`~hertzchain.integrate.batch.systems.systems` reads them: (member, bead) arrays padded to the
    longest chain (``n_beads``) with its last bead.

    Built by :func:`ragged`. Row i of ``systems``'s arrays is ``models[i].system()``'s in its
    first ``n_each[i] + 1`` contact slots and bodies (the slots a member's engine buffers hold);
    the rest is padding.
    """

    n_beads: int
    n_each: np.ndarray
    has_wall: bool
    law_name: str
    materials: tuple
    bead_material: np.ndarray
    striker_material: np.ndarray
    wall_material: np.ndarray
    diameters: np.ndarray
    offsets: np.ndarray
    striker_diameter: np.ndarray
    striker_velocity: np.ndarray
    law_parameter: np.ndarray
    precompression: np.ndarray
    models: list

    @property
    def n_members(self) -> int:
        """Number of members M."""
        return len(self.models)

    def model(self, i: int) -> Model:
        """Member ``i``'s model.

        Parameters
        ----------
        i:
            Member index, 0..M-1.

        Returns
        -------
        Model
            The model the member was built from.
        """
        return self.models[i]


def ragged(models: Sequence[Model]) -> Ragged:
    """The :class:`Ragged` members of models that share the end and the contact law's kind.

    Parameters
    ----------
    models:
        Models whose ``layout_key`` differs at most in the number of beads.

    Returns
    -------
    Ragged
        Member i is ``models[i]`` (same numbers, so the same results).
    """
    keys = [layout_key(m) for m in models]
    if not models or keys[0] is None or any(k is None or k[1:] != keys[0][1:] for k in keys):
        raise ConfigError("models", "ragged members must share the end (wall or none) and the contact law's kind "
                          "(elastic, viscoelastic or dashpot)")
    m0 = models[0]
    has_wall = m0.wall.present
    n_each = np.array([k[0] for k in keys], dtype=np.int64)
    nmax = int(n_each.max())
    table: dict[int, int] = {}
    materials: list[Material] = []

    def idx(mat: Material) -> int:
        k = table.get(id(mat))
        if k is None:
            k = table[id(mat)] = len(materials)
            materials.append(mat)
        return k

    diameters = np.empty((len(models), nmax))
    offsets = np.zeros((len(models), nmax))
    bead_material = np.empty((len(models), nmax), dtype=np.int64)
    rows: dict[tuple, list[int]] = {}
    for i, (mdl, n) in enumerate(zip(models, n_each.tolist())):
        chain = mdl.chain
        diameters[i, :n] = chain.diameters
        diameters[i, n:] = chain.diameters[-1]  # padding: finite numbers, never used
        offsets[i, :n] = chain.offsets
        mats = chain.materials
        first = mats[0]
        one = all(x is first for x in mats)  # one material throughout (the usual chain): one lookup
        key = ("one", id(first), n) if one else tuple(map(id, mats))
        row = rows.get(key)
        if row is None:
            row = rows[key] = [idx(first)] * n if one else [idx(x) for x in mats]
        bead_material[i, :n] = row
        bead_material[i, n:] = row[-1]
    scalars = np.array([(x.striker.diameter, x.striker.velocity, float(x.law.parameter), x.precompression)
                        for x in models], dtype=float).T.copy()
    return Ragged(n_beads=nmax, n_each=n_each, has_wall=has_wall, law_name=m0.law.name,
                  bead_material=bead_material,
                  striker_material=np.array([idx(x.striker.material) for x in models], dtype=np.int64),
                  wall_material=np.array([idx(x.wall_material) if has_wall else -1 for x in models], dtype=np.int64),
                  materials=tuple(materials), diameters=diameters, offsets=offsets, striker_diameter=scalars[0],
                  striker_velocity=scalars[1], law_parameter=scalars[2], precompression=scalars[3],
                  models=list(models))
