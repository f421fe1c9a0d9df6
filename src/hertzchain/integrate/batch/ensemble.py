"""Many members of one layout as arrays: the ensembles the batched engines run.

A Monte Carlo over manufacturing tolerances or a parameter sweep runs 1e4 to 1e6 chains that
differ only in a few numbers (bead diameters, offsets, impact velocity...). Building one
:class:`~hertzchain.Model`, one ``System`` and one packed work array
per member costs ~0.2 ms of Python each, which at 1e5 members is more than the physics. An
:class:`~hertzchain.Ensemble` holds the members as (member, bead) arrays instead, checked for
every member at once, and :func:`hertzchain.integrate.batch.systems.systems` turns them into the
engine's arrays with array code: the formulas of ``Model.system()`` applied along a leading
member axis, so that every member's numbers are bit for bit those of ``Model.system()`` of that
member alone (the batched engine's results stay identical to :func:`hertzchain.simulate`;
tests/test_ensemble.py checks it).

Members of one ensemble share the number of beads, whether there is a wall and the contact law's
kind (:func:`layout_key`); everything else may differ per member. Members that differ in the
number of beads too are a :class:`~hertzchain.integrate.batch.ragged.Ragged` set.
"""

from __future__ import annotations

import json
from typing import Callable, Sequence

import numpy as np

from ...chain import Chain
from ...contact import Dashpot, Elastic, Viscoelastic
from ...errors import ConfigError
from ...materials import Material
from ...model import Model, Striker, Wall
from ...laws import spec_of
from ...laws.spec import LawObject

__all__ = ["Ensemble", "same_layout", "layout_key"]


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

    # Set once by _set (the instance is read-only after construction): declared for readers and mypy.
    n_beads: int
    has_wall: bool
    law_name: str
    materials: tuple
    bead_material: np.ndarray
    striker_material: np.ndarray
    wall_material: np.ndarray
    wall_material_given: bool | None
    diameters: np.ndarray
    offsets: np.ndarray
    striker_diameter: np.ndarray
    striker_velocity: np.ndarray
    law_parameter: np.ndarray
    precompression: np.ndarray

    def __init__(self, base: Model, *, n_members: int | None = None, diameters=None, offsets=None,
                 striker_velocity=None, striker_diameter=None, law_parameter=None, precompression=None) -> None:
        if not isinstance(base, Model):
            raise ConfigError("base", f"must be a hertzchain Model, got {type(base).__name__}")
        if layout_key(base) is None:
            if base.law.name in _LAW_FIELD:
                raise ConfigError("base", "an Ensemble holds models of the paper's kind (sphere striker and beads, a "
                                  "flat wall or a free end, no gravity); others go through simulate_batch as a "
                                  "list of models")
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
        # (a model of the paper's kind, layout_key: body0 is its striker)
        materials, index = _material_table([base.body0.material, *base.chain.materials, base.wall_material])
        self._set(n_beads=n, has_wall=base.wall.present, law_name=base.law.name, materials=materials,
                  bead_material=np.broadcast_to(index[1:n + 1], (m, n)),
                  striker_material=np.full(m, index[0]),
                  wall_material=np.full(m, index[n + 1] if base.wall.present else -1),
                  wall_material_given=base.wall.material is not None,
                  diameters=_per_bead(diameters, base.chain.diameters, m, "chain.diameters"),
                  offsets=_per_bead(offsets, np.asarray(base.chain.offsets), m, "chain.offsets"),
                  striker_diameter=_per_member(striker_diameter, m, "striker.diameter_mm", base.body0.diameter),
                  striker_velocity=_per_member(striker_velocity, m, "striker.velocity", base.body0.velocity),
                  law_parameter=_per_member(law_parameter, m, _LAW_FIELD[base.law.name], base.law.parameter),
                  precompression=_per_member(precompression, m, "chain.precompression", base.precompression))
        if not spec_of(base.law).dissipative and np.any(self.law_parameter != 0.0):
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
        # (models of the paper's kind, layout_key: body0 is the striker)
        scalars = np.array([(x.body0.diameter, x.body0.velocity, float(x.law.parameter), x.precompression)
                            for x in models], dtype=np.float64).T.copy()
        self = cls.__new__(cls)
        self._set(n_beads=n, has_wall=has_wall, law_name=m0.law.name, materials=None,
                  # one row for all when the members share their materials (systems() then
                  # looks the material columns up once: a stride-0 first axis says so)
                  bead_material=np.broadcast_to(bead_rows[0], (len(models), n)) if len(rows) == 1
                  else np.array(bead_rows),
                  striker_material=np.array([idx(x.body0.material) for x in models], dtype=np.int64),
                  wall_material=np.array([-1 if (wm := x.wall_material) is None else idx(wm) for x in models],
                                         dtype=np.int64),
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
        make: dict[str, Callable[[float], LawObject]] = {
            "elastic": lambda p: Elastic(), "viscoelastic": lambda p: Viscoelastic(A=p),
            "dashpot": lambda p: Dashpot(gamma=p)}
        law = make[self.law_name](float(self.law_parameter[i]))
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
                wall_mat = names[self.wall_material[i]] if given[i] else names[bm[0]]
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
        ``(N, has_wall, law name)``; None for what the array set-up does not compute: the
        size-scaled viscoelastic law (its damping depends on each contact's masses) and the models
        beyond the paper's (``Model.plain`` is False: a given striker mass or face, cylinders,
        mass-in-mass beads, a protected body, gravity) and a chain of zero beads, which are set up
        member by member.
    """
    if model.law.name not in _LAW_FIELD or not model.plain or not model.chain.n_beads:
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
    if key is None:
        return False
    # once per distinct model: a tolerance ensemble's members are one nominal model, repeated
    seen = {id(models[0])}
    for m in models:
        if id(m) not in seen:
            seen.add(id(m))
            if layout_key(m) != key:
                return False
    return True
