"""Many members of one layout as arrays: the vectorised set-up of the batched engines.

A Monte Carlo over manufacturing tolerances or a parameter sweep runs 1e4 to 1e6 chains that
differ only in a few numbers (bead diameters, offsets, impact velocity...). Building one
:class:`~hertzchain.Model`, one ``System`` and one packed work array
per member costs ~0.2 ms of Python each, which at 1e5 members is more than the physics. An
:class:`~hertzchain.Ensemble` holds the members as (member, bead) arrays instead, and ``systems`` turns
them into the engine's arrays with array code: the formulas of ``Model.system()`` (Hertz
constants, paper eq. 1; masses; precompression; offsets) applied along a leading member axis,
operation for operation, so that every member's numbers are bit for bit those of
``Model.system()`` of that member alone (the batched engine's results stay identical to
:func:`hertzchain.simulate`; tests/test_ensemble.py checks it).

Members of one ensemble share the number of beads, whether there is a wall and the contact law's
kind; everything else may differ per member. A :class:`Ragged` set of members (built by
:func:`ragged`) may also differ in the number of beads: a design search's generation of chains
of many lengths is then one ``systems`` call too.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..chain import Chain
from ..contact import LAW_CODES, Dashpot, Elastic, Viscoelastic
from ..errors import ConfigError
from ..materials import Material
from ..model import Model, Striker, Wall

__all__ = ["Ensemble", "Ragged", "Systems", "ragged", "systems", "same_layout", "layout_key"]

_LAW_FIELD = {"elastic": "contact.law", "viscoelastic": "contact.A", "dashpot": "contact.gamma"}


def _per_member(x, n: int, name: str, default: float) -> np.ndarray:
    """A scalar or None broadcast to ``n`` members, or a length-n vector, as float64 (a copy: the
    ensemble's arrays are read-only, the caller's stay as they were)."""
    a = np.array(default if x is None else x, dtype=float)
    if a.ndim == 0:
        return np.full(n, float(a))
    if a.shape != (n,):
        raise ConfigError(name, f"needs one value per member ({n}), got shape {a.shape}")
    return a


def _first_bad(mask: np.ndarray) -> tuple[int, ...]:
    return tuple(int(i) for i in np.argwhere(mask)[0])


class Ensemble:
    """Members sharing one layout, described by a base model and per-member arrays.

    Each member is the base :class:`~hertzchain.Model` with the fields given here replaced
    by its row; fields left out are the base's. The members share the number of beads N, the
    end (wall or free end) and the contact law's kind (elastic, viscoelastic or dashpot).

    Parameters
    ----------
    base:
        The model every member starts from.
    n_members:
        Number of members M; needed only when no per-member array says it.
    diameters:
        Bead diameters phi_n [m], shape (M, N) (or (N,) for all members).
    offsets:
        Perpendicular offsets e_n of the bead centres [m], shape (M, N) (or (N,)).
    striker_velocity:
        Impact velocity [m/s], shape (M,) or a scalar.
    striker_diameter:
        Striker diameter [m], shape (M,) or a scalar.
    law_parameter:
        The contact law's constant, shape (M,) or a scalar: A [s] (viscoelastic) or gamma
        [N s/m] (dashpot); not for the elastic law.
    precompression:
        Static force [N] on beads 1..N, shape (M,) or a scalar (needs a wall and no offsets).

    Raises
    ------
    ConfigError
        Naming the field and the first member whose value is invalid.

    Examples
    --------
    A Monte Carlo over diameter tolerances of 0.1 % (1 sigma)::

        base = Model(paper_chain("chain1"))
        z = np.random.default_rng(1).standard_normal((10_000, base.chain.n_beads))
        ens = Ensemble(base, diameters=base.chain.diameters * (1 + 1e-3 * z))
        ds = simulate_batch(ens, 2e-3)
    """

    def __init__(self, base: Model, *, n_members: int | None = None, diameters=None, offsets=None,
                 striker_velocity=None, striker_diameter=None, law_parameter=None, precompression=None) -> None:
        if not isinstance(base, Model):
            raise ConfigError("base", f"must be a hertzchain Model, got {type(base).__name__}")
        if layout_key(base) is None:
            raise ConfigError("contact.law", f"an Ensemble computes the elastic, viscoelastic and dashpot laws; "
                              f"'{base.law.name}' members go through simulate_batch as a list of models")
        n = base.chain.n_beads
        sizes = [np.shape(x)[0] for x in (diameters, offsets) if x is not None and np.ndim(x) == 2]
        sizes += [np.shape(x)[0] for x in (striker_velocity, striker_diameter, law_parameter, precompression)
                  if x is not None and np.ndim(x) == 1]
        if n_members is not None:
            sizes.append(int(n_members))
        if not sizes:
            raise ConfigError("n_members", "give the number of members or at least one per-member array")
        m = sizes[0]
        if m < 1 or any(s != m for s in sizes):
            raise ConfigError("n_members", "the per-member arrays disagree on the number of members: "
                              f"{sorted(set(sizes))}")
        materials, index = _material_table([base.striker.material, *base.chain.materials, base.wall_material])
        self._set(n_beads=n, has_wall=base.wall.present, law_name=base.law.name, materials=materials,
                  bead_material=np.broadcast_to(index[1:n + 1], (m, n)),
                  striker_material=np.full(m, index[0]),
                  wall_material=np.full(m, index[n + 1] if base.wall.present else -1),
                  wall_material_given=base.wall.material is not None,
                  diameters=_per_bead(diameters, base.chain.diameters, m, "chain.diameters"),
                  offsets=_per_bead(offsets, base.chain.offsets, m, "chain.offsets"),
                  striker_diameter=_per_member(striker_diameter, m, "striker.diameter_mm", base.striker.diameter),
                  striker_velocity=_per_member(striker_velocity, m, "striker.velocity", base.striker.velocity),
                  law_parameter=_per_member(law_parameter, m, _LAW_FIELD[base.law.name], base.law.parameter),
                  precompression=_per_member(precompression, m, "chain.precompression", base.precompression))
        if base.law.name == "elastic" and np.any(self.law_parameter != 0.0):
            raise ConfigError("contact.law", "the elastic law has no parameter: give law_parameter only for a "
                              "viscoelastic (A) or dashpot (gamma) base model")
        self._validate()

    def _set(self, **fields) -> None:
        for k, v in fields.items():
            if isinstance(v, np.ndarray) and v.flags.writeable:
                v.setflags(write=False)
            object.__setattr__(self, k, v)

    def __setattr__(self, name, value):
        raise AttributeError("an Ensemble is immutable")

    @classmethod
    def from_models(cls, models: Sequence[Model]) -> "Ensemble":
        """The ensemble of a list of models that share a layout (see ``same_layout``).

        Parameters
        ----------
        models:
            Models with the same number of beads, end and contact law kind.

        Returns
        -------
        Ensemble
            Member i is ``models[i]`` (same numbers, so the same results).
        """
        if not same_layout(models):
            raise ConfigError("models", "an ensemble's members must share the number of beads, the end (wall "
                              "or none) and the contact law's kind (elastic, viscoelastic or dashpot)")
        m0 = models[0]
        n = m0.chain.n_beads
        table: dict[int, int] = {}
        materials: list[Material] = []

        def idx(mat: Material) -> int:
            k = table.get(id(mat))
            if k is None:
                k = table[id(mat)] = len(materials)
                materials.append(mat)
            return k

        # Rows of material indices, looked up once per distinct tuple of materials (tolerance
        # ensembles share one tuple of Material objects, so this is one dict hit per member).
        rows: dict[tuple[int, ...], np.ndarray] = {}
        bead_rows = []
        for mdl in models:
            key = tuple(map(id, mdl.chain.materials))
            row = rows.get(key)
            if row is None:
                row = rows[key] = np.array([idx(x) for x in mdl.chain.materials], dtype=np.int64)
            bead_rows.append(row)
        has_wall = m0.wall.present
        # the per-member scalars in one pass (a design's generation builds ~10 small ensembles)
        scalars = np.array([(x.striker.diameter, x.striker.velocity, float(x.law.parameter), x.precompression)
                            for x in models], dtype=float).T.copy()
        self = cls.__new__(cls)
        self._set(n_beads=n, has_wall=has_wall, law_name=m0.law.name, materials=None,
                  # one row for all when the members share their materials (systems() then
                  # looks the material columns up once: a stride-0 first axis says so)
                  bead_material=np.broadcast_to(bead_rows[0], (len(models), n)) if len(rows) == 1
                  else np.array(bead_rows),
                  striker_material=np.array([idx(x.striker.material) for x in models], dtype=np.int64),
                  wall_material=np.array([idx(x.wall_material) if has_wall else -1 for x in models], dtype=np.int64),
                  wall_material_given=None,
                  wall_given=np.array([x.wall.material is not None for x in models]),
                  diameters=np.array([x.chain.diameters for x in models], dtype=float),
                  offsets=np.array([x.chain.offsets for x in models], dtype=float),
                  striker_diameter=scalars[0], striker_velocity=scalars[1], law_parameter=scalars[2],
                  precompression=scalars[3])
        object.__setattr__(self, "materials", tuple(materials))
        object.__setattr__(self, "_models", list(models))
        return self

    _ROWS = ("bead_material", "striker_material", "wall_material", "diameters", "offsets", "striker_diameter",
             "striker_velocity", "law_parameter", "precompression")

    def _copy(self, rows=None, **arrays) -> "Ensemble":
        """A new ensemble: members ``rows`` (all when None) of this one, ``arrays`` replaced."""
        new = type(self).__new__(type(self))
        fields = dict(vars(self))
        models = fields.pop("_models", None)
        given = fields.pop("wall_given", None)
        if rows is not None:
            fields.update({k: np.ascontiguousarray(fields[k][rows]) for k in self._ROWS})
            given = None if given is None else given[rows]
            models = None if models is None else [models[i] for i in np.asarray(rows).tolist()]
        m = fields["diameters"].shape[0]
        names = {"diameters": "chain.diameters", "offsets": "chain.offsets"}
        for k, x in arrays.items():
            fields[k] = _per_bead(x, fields[k][0], m, names[k]) if k in names else \
                _per_member(x, m, k, 0.0)
        new._set(**fields)
        if given is not None:
            new._set(wall_given=given)
        if models is not None and not arrays:
            object.__setattr__(new, "_models", models)
        if arrays:
            new._validate()
        return new

    def subset(self, rows) -> "Ensemble":
        """The ensemble of some members.

        Parameters
        ----------
        rows:
            Member indices (or a slice or boolean mask) to keep, in that order.

        Returns
        -------
        Ensemble
            Member i is member ``rows[i]`` of this one.
        """
        rows = np.arange(self.n_members)[rows]  # indices, whether given a slice, a mask or indices
        return self._copy(np.atleast_1d(rows))

    def replace(self, **arrays) -> "Ensemble":
        """The same members with some per-member arrays replaced (checked as in the constructor).

        Parameters
        ----------
        **arrays:
            Any of ``diameters``, ``offsets`` [m] (M, N); ``striker_velocity`` [m/s],
            ``striker_diameter`` [m], ``law_parameter``, ``precompression`` [N] (M,).

        Returns
        -------
        Ensemble
            A new ensemble (this one is unchanged).
        """
        unknown = set(arrays) - {"diameters", "offsets", "striker_velocity", "striker_diameter", "law_parameter",
                                 "precompression"}
        if unknown:
            raise ConfigError(sorted(unknown)[0], "is not a per-member array of an Ensemble")
        return self._copy(None, **arrays)

    # ------------------------------------------------------------------ properties
    @property
    def n_members(self) -> int:
        """Number of members M."""
        return int(self.diameters.shape[0])

    def __len__(self) -> int:
        return self.n_members

    def __iter__(self):
        """The members as :class:`~hertzchain.Model` objects (built one by one: for inspection)."""
        return (self.model(i) for i in range(self.n_members))

    def _wall_given(self) -> np.ndarray:
        given = getattr(self, "wall_given", None)
        return np.full(self.n_members, bool(self.wall_material_given)) if given is None else given

    def _validate(self) -> None:
        """The checks of Chain, Striker and Model, on every member at once (first bad member named)."""
        d, e = self.diameters, self.offsets
        bad = ~np.isfinite(d) | (d <= 0)
        if bad.any():
            i, j = _first_bad(bad)
            raise ConfigError(f"chain.diameters[{j}]", f"member {i}: diameter of bead {j + 1} must be a positive "
                              f"finite number, got {float(d[i, j])!r}")
        if not np.all(np.isfinite(e)):
            i, j = _first_bad(~np.isfinite(e))
            raise ConfigError("chain.offsets", f"member {i}: offsets must be finite (bead {j + 1}: {float(e[i, j])!r})")
        radii = d / 2
        de = np.abs(np.diff(e, axis=1))
        far = de >= 0.5 * (radii[:, :-1] + radii[:, 1:])
        if far.any():
            i, j = _first_bad(far)
            raise ConfigError("chain.offsets", f"member {i}: beads {j + 1} and {j + 2} are offset by {de[i, j]:.3g} m, "
                              "more than half the sum of their radii; the contact would not be a head-on Hertz contact")
        # Model: the striker flies along the axis, so bead 1's offset must stay below (R_s + R_1) / 2
        reach = 0.5 * (self.striker_diameter / 2 + radii[:, 0])
        miss = np.abs(e[:, 0]) >= reach
        if miss.any():
            i = int(np.flatnonzero(miss)[0])
            raise ConfigError("chain.offsets", f"member {i}: bead 1 is offset by {abs(float(e[i, 0])):.3g} m from the "
                              f"striker's line of flight, more than half the sum of their radii ({reach[i]:.3g} m); "
                              "the striker would not hit it head-on (or would miss the chain)")
        for name, x, field in (("diameter", self.striker_diameter, "striker.diameter_mm"),
                               ("velocity", self.striker_velocity, "striker.velocity")):
            bad = ~np.isfinite(x) | (x <= 0)
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise ConfigError(field, f"member {i}: the striker {name} must be a positive number, "
                                  f"got {float(x[i])!r}")
        p = self.law_parameter
        bad = ~np.isfinite(p) | (p < 0)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ConfigError(_LAW_FIELD[self.law_name],
                              f"member {i}: must be a finite number >= 0, got {float(p[i])!r}")
        f0 = self.precompression
        bad = ~np.isfinite(f0) | (f0 < 0)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ConfigError("chain.precompression", f"member {i}: must be a force >= 0 in N, got {float(f0[i])!r}")
        pushed = f0 > 0
        if pushed.any() and not self.has_wall:
            raise ConfigError("chain.precompression", "a static precompression needs a wall to push against")
        both = pushed & np.any(e != 0, axis=1)
        if both.any():
            raise ConfigError("chain.precompression", f"member {int(np.flatnonzero(both)[0])}: precompression "
                              "together with bead offsets is not supported")

    # ------------------------------------------------------------------ members as objects
    def model(self, i: int) -> Model:
        """Member ``i`` as a :class:`~hertzchain.Model` (for inspection; the engines never need it).

        Parameters
        ----------
        i:
            Member index, 0..M-1.

        Returns
        -------
        Model
            A model whose ``system()`` gives exactly the member's arrays.
        """
        models = getattr(self, "_models", None)
        if models is not None:
            return models[i]
        mats = self.materials
        law = {"elastic": lambda p: Elastic(), "viscoelastic": lambda p: Viscoelastic(A=p),
               "dashpot": lambda p: Dashpot(gamma=p)}[self.law_name](float(self.law_parameter[i]))
        wall = Wall("flat", mats[self.wall_material[i]] if self._wall_given()[i] else None) if self.has_wall \
            else Wall("none")
        return Model(Chain(self.diameters[i], tuple(mats[k] for k in self.bead_material[i]), self.offsets[i]),
                     Striker(float(self.striker_diameter[i]), float(self.striker_velocity[i]),
                             mats[self.striker_material[i]]),
                     wall, law, float(self.precompression[i]))

    def describe(self) -> list[str]:
        """Every member's ``Model.describe()`` as JSON text (the batch result's ``model`` variable).

        Returns
        -------
        list of str
            ``json.dumps(self.model(i).describe())`` for every member i, built from the arrays.
        """
        models = getattr(self, "_models", None)
        if models is not None and not all(
                type(m.striker.diameter) is float and type(m.striker.velocity) is float  # noqa: E721
                and type(m.precompression) is float and type(m.law.parameter) is float for m in models):  # noqa: E721
            # a member holds an int where the arrays hold floats ("1" is not "1.0" in JSON): its own text
            return [json.dumps(m.describe()) for m in models]
        names = [json.dumps(m.name) for m in self.materials]
        law_key = {"viscoelastic": "A", "dashpot": "gamma"}.get(self.law_name)
        # json.dumps writes a finite float as float.__repr__ does: the lists are joined directly
        # (~4x faster than json.dumps of the member's dict, the same text).
        d_mm = (self.diameters * 1e3).tolist()
        e_mm = (self.offsets * 1e3).tolist()
        # rows of +0.0 offsets (every bit zero; -0.0 prints differently) share one text
        aligned = ~np.any(np.ascontiguousarray(self.offsets).view(np.int64) != 0, axis=1)
        zeros = "[" + ", ".join(["0.0"] * self.n_beads) + "]"
        sd_mm = (self.striker_diameter * 1e3).tolist()
        vel = self.striker_velocity.tolist()
        law_p = self.law_parameter.tolist()
        pre = self.precompression.tolist()
        given = self._wall_given()
        wall_type = '"flat"' if self.has_wall else '"none"'
        mats_text: dict[bytes, str] = {}
        out = []
        rep = float.__repr__
        for i in range(self.n_members):
            bm = self.bead_material[i]
            key = bm.tobytes()
            mats = mats_text.get(key)
            if mats is None:
                first = bm[0]
                mats = mats_text[key] = names[first] if bool(np.all(bm == first)) else \
                    "[" + ", ".join(names[k] for k in bm) + "]"
            contact = f'{{"law": "{self.law_name}", "{law_key}": {rep(law_p[i])}}}' if law_key else \
                f'{{"law": "{self.law_name}"}}'
            wall_mat = "null"
            if self.has_wall:
                wall_mat = names[self.wall_material[i]] if given[i] else names[bm[-1]]
            out.append(
                '{"chain": {"diameters_mm": [' + ", ".join(map(rep, d_mm[i])) + '], "materials": ' + mats
                + ', "offsets_mm": ' + (zeros if aligned[i] else "[" + ", ".join(map(rep, e_mm[i])) + "]")
                + '}, "striker": {"diameter_mm": '
                + rep(sd_mm[i]) + ', "velocity": ' + rep(vel[i]) + ', "material": ' + names[self.striker_material[i]]
                + '}, "wall": {"type": ' + wall_type + ', "material": ' + wall_mat + '}, "contact": ' + contact
                + ', "precompression": ' + rep(pre[i]) + "}")
        return out


def _per_bead(x, default: np.ndarray, m: int, name: str) -> np.ndarray:
    n = default.size
    if x is None:
        return np.broadcast_to(default, (m, n))
    a = np.asarray(x, dtype=float)
    if a.shape == (n,):
        return np.broadcast_to(a, (m, n))
    if a.shape != (m, n):
        raise ConfigError(name, f"needs shape (members, beads) = ({m}, {n}) or ({n},), got {a.shape}")
    return np.array(a, order="C")  # a copy (see _per_member)


def _material_table(mats: list[Material | None]) -> tuple[tuple[Material, ...], np.ndarray]:
    table: dict[int, int] = {}
    unique: list[Material] = []
    index = []
    for mat in mats:
        if mat is None:
            index.append(-1)
            continue
        k = table.setdefault(id(mat), len(unique))
        if k == len(unique):
            unique.append(mat)
        index.append(k)
    return tuple(unique), np.array(index, dtype=np.int64)


def layout_key(model: Model) -> tuple[int, bool, str] | None:
    """The layout an ensemble's members share: (number of beads, wall present, contact law kind).

    Parameters
    ----------
    model:
        Any model.

    Returns
    -------
    tuple or None
        ``(N, has_wall, law name)``; None for a law the array set-up does not compute (the
        size-scaled viscoelastic law: its damping depends on each contact's masses).
    """
    if model.law.name not in _LAW_FIELD:
        return None
    return model.chain.n_beads, model.wall.present, model.law.name


def same_layout(models: Sequence[Model]) -> bool:
    """True when the models share the number of beads, the end and the contact law's kind.

    Parameters
    ----------
    models:
        Any models.

    Returns
    -------
    bool
        Whether ``Ensemble.from_models`` accepts them (never for the size-scaled viscoelastic
        law, see ``layout_key``).
    """
    if len(models) == 0 or not all(isinstance(m, Model) for m in models):
        return False
    key = layout_key(models[0])
    return key is not None and all(layout_key(m) == key for m in models)


@dataclass(frozen=True)
class Ragged:
    """Members of one end and contact law kind but any numbers of beads, as :func:`systems` reads
    them: (member, bead) arrays padded to the longest chain (``n_beads``) with its last bead.

    Built by :func:`ragged`. Row i of :func:`systems`'s arrays is ``models[i].system()``'s in its
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


@dataclass
class Systems:
    """``System`` arrays of every member, stacked along a leading member axis.

    Row i of each array is exactly the corresponding array of ``ensemble.model(i).system()``.
    Shapes: (M, N + 2) for bodies, (M, N + 1) for contact slots, (M,) per member.
    """

    mass: np.ndarray
    inv_mass: np.ndarray
    kappa: np.ndarray
    damping: np.ndarray
    d0: np.ndarray
    de: np.ndarray
    dx0: np.ndarray
    rsum: np.ndarray
    fext: np.ndarray
    u0: np.ndarray
    v0: np.ndarray
    yield_force: np.ndarray
    law: int
    misaligned: np.ndarray   # (M,) bool
    has_wall: bool
    bead_mass: np.ndarray    # (M, N) kg, Chain.masses of every member
    max_overlap: np.ndarray  # (M, N + 1) m, System.max_overlap()
    max_frequency: np.ndarray  # (M,) rad/s, System.max_frequency()

    @property
    def general(self) -> np.ndarray:
        """(M,) True where the general force loop is needed (dissipation or offsets)."""
        return (self.law != 0) | self.misaligned


def _scalar_map(fn, x: np.ndarray) -> np.ndarray:
    """``fn`` applied with Python float arithmetic to every distinct value of ``x``.

    Scalar powers (``x ** 2``, ``x ** 3`` on a Python float or NumPy scalar) go through the C
    library's pow, while NumPy's array power may use a vector routine that differs in the last
    bit; where Model.system() computes on scalars, so does this, once per distinct value.
    """
    if x.size <= _SMALL:  # a few members: sorting out the distinct values costs more than fn
        return np.array([fn(v) for v in x.ravel().tolist()], dtype=float).reshape(x.shape)
    vals, inv = np.unique(x, return_inverse=True)
    return np.array([fn(float(v)) for v in vals], dtype=float)[inv.reshape(x.shape)]


#: Up to this many values, :func:`_scalar_map` calls ``fn`` on each (np.unique's ~10 us would
#: cost more); the values are the same either way.
_SMALL = 32


def systems(ens: Ensemble | Ragged, start: int = 0, stop: int | None = None) -> Systems:
    """The engine's arrays of every member: ``Model.system()`` vectorised over the members.

    Parameters
    ----------
    ens:
        The members: one layout (:class:`Ensemble`), or any numbers of beads (:class:`Ragged`:
        then row i holds member i's arrays in its first N_i + 1 contact slots and bodies, and
        ``max_frequency`` is over its bodies 0..N_i).
    start, stop:
        The range of members to compute (default: all). The batched engine computes blocks of
        a few thousand members, whose arrays stay in the caches.

    Returns
    -------
    Systems
        Per-member arrays, bit for bit those of each member's ``Model.system()`` (same
        operations in the same order: Hertz constants kappa = 1 / (theta_sum sqrt(1/R + 1/R'))
        of paper eq. 1, masses rho pi phi^3 / 6, the precompression overlaps, the offsets'
        geometry), plus ``max_overlap`` and ``max_frequency`` (the step's bounds).
    """
    sel = slice(start, stop)
    d = ens.diameters[sel]
    m, n = d.shape
    bead_material, striker_material = ens.bead_material[sel], ens.striker_material[sel]
    wall_material, striker_diameter = ens.wall_material[sel], ens.striker_diameter[sel]
    striker_velocity, precompression = ens.striker_velocity[sel], ens.precompression[sel]
    law_parameter = ens.law_parameter[sel]
    # Ragged members (:class:`Ragged`): member i has n_each[i] beads, its arrays padded to n; the
    # few slots where a shorter chain differs (its wall contact, the slots past its end) are set
    # after the array code, which is element for element the same as for one layout.
    nn = getattr(ens, "n_each", None)
    if nn is not None:
        nn = nn[sel]
        every = np.arange(m)
    mats = ens.materials
    rho_t = np.array([x.density for x in mats])
    theta_t = np.array([x.theta for x in mats])
    sigma_t = np.array([np.nan if x.yield_stress is None else x.yield_stress for x in mats])

    # Material columns once when every member has the same materials (the usual ensemble): rows
    # of shape (1, ...) then broadcast against the members' geometry, same numbers.
    if nn is None and (bead_material.strides[0] == 0 or bool(np.all(bead_material == bead_material[:1]))) and \
            bool(np.all(striker_material == striker_material[0])) and bool(np.all(wall_material == wall_material[0])):
        bead_mat, striker_mat, wall_mat = bead_material[:1], striker_material[:1], wall_material[:1]
    else:
        bead_mat, striker_mat, wall_mat = bead_material, striker_material, wall_material
    mm = striker_mat.size

    # masses: the striker's with scalar arithmetic (Striker.mass), the beads' as Chain.masses
    striker_mass = np.empty(m)
    for k in (striker_mat.tolist() if mm == 1 else np.unique(striker_material).tolist()):
        rows = slice(None) if mm == 1 else striker_material == k
        rho = float(rho_t[k])
        striker_mass[rows] = _scalar_map(lambda dia: rho * math.pi * dia**3 / 6.0, striker_diameter[rows])
    bead_mass = np.ascontiguousarray(rho_t[bead_mat]) * math.pi * np.ascontiguousarray(d) ** 3 / 6.0
    mass = np.empty((m, n + 2))
    mass[:, 0] = striker_mass
    mass[:, 1:n + 1] = bead_mass
    mass[:, n + 1] = np.inf
    inv_mass = np.zeros((m, n + 2))
    inv_mass[:, :n + 1] = 1.0 / mass[:, :n + 1]

    r = np.empty((m, n + 1))
    r[:, 0] = striker_diameter / 2
    r[:, 1:] = d / 2.0
    theta = np.empty((mm, n + 1))
    theta[:, 0] = theta_t[striker_mat]
    theta[:, 1:] = theta_t[bead_mat]
    sigma = np.empty((mm, n + 1))
    sigma[:, 0] = sigma_t[striker_mat]
    sigma[:, 1:] = sigma_t[bead_mat]
    nk = n + 1 if ens.has_wall else n
    inv_r = (np.empty if nn is None else np.ones)((m, nk))  # ragged: finite in every padding slot
    t_sum = (np.empty if nn is None else np.ones)((mm, nk))
    s_min = (np.empty if nn is None else np.ones)((mm, nk))
    inv_r[:, :n] = 1.0 / r[:, :-1] + 1.0 / r[:, 1:]
    t_sum[:, :n] = theta[:, :-1] + theta[:, 1:]
    s_min[:, :n] = np.fmin(sigma[:, :-1], sigma[:, 1:])
    if ens.has_wall and nn is None:
        inv_r[:, n] = 1.0 / r[:, -1]
        t_sum[:, n] = theta[:, -1] + theta_t[wall_mat]
        s_min[:, n] = np.fmin(sigma[:, -1], sigma_t[wall_mat])
    elif ens.has_wall:  # contact N_i of every member, the same operations
        inv_r[every, nn] = 1.0 / r[every, nn]
        t_sum[every, nn] = theta[every, nn] + theta_t[wall_mat]
        s_min[every, nn] = np.fmin(sigma[every, nn], sigma_t[wall_mat])
    kappa = np.zeros((m, n + 1))
    fy = np.full((m, n + 1), np.inf)
    kappa[:, :nk] = 1.0 / (t_sum * np.sqrt(inv_r))
    c = 3.0 * (1.0 / inv_r) / (4.0 * (0.75 / t_sum))
    with np.errstate(invalid="ignore"):
        fy[:, :nk] = np.where(np.isnan(s_min), np.inf, (math.pi * s_min) ** 3 * c**2)
    if nn is not None:  # no contact past a member's chain (nor at a free end): kappa 0, no limit
        past = np.arange(n + 1) >= (nn + (1 if ens.has_wall else 0))[:, None]
        kappa[past] = 0.0
        fy[past] = np.inf

    damping = np.where(kappa > 0, law_parameter[:, None], 0.0)
    d0 = np.zeros((m, n + 1))
    fext = np.zeros((m, n + 2))
    pushed = np.flatnonzero(precompression > 0)
    if pushed.size and nn is None:
        f0 = precompression[pushed]
        # row by row, as Model.system() does (a contiguous (N,) array to the power 2/3)
        for row, i in zip(f0[:, None] / np.ascontiguousarray(kappa[pushed, 1:]), pushed):
            d0[i, 1:] = np.ascontiguousarray(row) ** (2.0 / 3.0)
        fext[pushed, 1] = precompression[pushed]
    elif pushed.size:
        for i in pushed.tolist():
            end = int(nn[i]) + 1
            d0[i, 1:end] = (precompression[i] / np.ascontiguousarray(kappa[i, 1:end])) ** (2.0 / 3.0)
        fext[pushed, 1] = precompression[pushed]

    e = np.zeros((m, n + 2))
    e[:, 1:n + 1] = ens.offsets[sel]
    de = e[:, 1:] - e[:, :-1]  # np.diff's own arithmetic
    de[:, n] = 0.0
    r2 = np.zeros((m, n + 2))
    r2[:, :n + 1] = r
    if nn is not None:
        de[every, nn] = 0.0  # a flat wall is unaffected by the last bead's offset
        r2[every, nn + 1] = 0.0  # the wall ghost's radius, as in System.rsum
    rsum = r2[:, :-1] + r2[:, 1:]
    dx0 = np.sqrt(np.maximum(rsum**2 - de**2, 0.0))
    v0 = np.zeros((m, n + 2))
    v0[:, 0] = striker_velocity

    # System.max_overlap and System.max_frequency, per member
    energy = 0.5 * mass[:, 0] * _scalar_map(lambda v: v**2, striker_velocity)
    if pushed.size and nn is None:
        energy = energy + np.sum(0.4 * kappa * d0**2.5, axis=1)
    elif pushed.size:
        stored = np.zeros(m)  # each member's sum over its own N_i + 1 slots (the same pairwise sum)
        pe = 0.4 * kappa * d0**2.5
        for i in pushed.tolist():
            stored[i] = np.sum(pe[i, :int(nn[i]) + 1])
        energy = energy + stored
    else:
        energy = energy + 0.0
    with np.errstate(divide="ignore"):
        dcap = np.where(kappa > 0, (2.5 * energy[:, None] / np.where(kappa > 0, kappa, 1.0)) ** 0.4, 0.0) + d0
    # System.max_frequency: Gershgorin bounds of stiffness and damping (System.damping_coefficients)
    k = 1.5 * kappa * np.sqrt(dcap)
    k_left = np.zeros((m, n + 1))
    k_left[:, 1:] = k[:, :n]
    omega2 = 2.0 * (k_left + k[:, :n + 1]) * inv_mass[:, :n + 1]
    if ens.law_name == "elastic":
        # beta = 0: sqrt(omega2 + 0.0) + 0.0 is sqrt(omega2) (omega2 >= 0), the same numbers
        bound = np.sqrt(omega2)
    else:
        if ens.law_name == "dashpot":
            c = np.where(kappa > 0, damping, 0.0)
        else:
            c = kappa * damping * np.sqrt(np.maximum(dcap, 0.0))
        c_left = np.zeros((m, n + 1))
        c_left[:, 1:] = c[:, :n]
        beta = 2.0 * (c_left + c[:, :n + 1]) * inv_mass[:, :n + 1]
        bound = np.sqrt(omega2 + 0.25 * beta**2) + 0.5 * beta
    if nn is not None:  # bodies 0..N_i only (the bounds are >= 0)
        bound = np.where(np.arange(n + 1) <= nn[:, None], bound, 0.0)
    w = np.max(bound, axis=1)
    return Systems(mass=mass, inv_mass=inv_mass, kappa=kappa, damping=damping, d0=d0, de=de, dx0=dx0, rsum=rsum,
                   fext=fext, u0=np.zeros((m, n + 2)), v0=v0, yield_force=fy, law=LAW_CODES[ens.law_name],
                   misaligned=np.any(de != 0.0, axis=1), has_wall=ens.has_wall, bead_mass=bead_mass,
                   max_overlap=dcap, max_frequency=w)
