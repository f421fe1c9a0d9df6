"""The design space: variables addressed by dotted paths into a run config, and chain shapes.

A design variable is any field of a run config (``striker.velocity``, ``chain.taper.q``,
``chain.diameters_mm[3]``), a range of list items (``chain.diameters_mm[16:30]``: one variable
per bead), or a parameter of a chain shape (``shape.exponent``; see :class:`Shape`). A variable
is

- real: ``[low, high]`` with floats, or ``{ low = , high = }``;
- integer: ``[low, high]`` with two integers (ints stay ints), or ``{ low = , high = , integer = true }``;
- categorical: a list of strings (``["AISI52100", "brass"]``) or ``{ choices = [...] }``;
- restricted to a catalogue of sizes: ``{ low = , high = , catalogue = "metric" }`` (or ``"inch"``,
  or a list of sizes in mm; see :mod:`hertzchain.design.catalogues`).

A list range may add ``monotone = "decreasing"`` (or ``"increasing"``, ``true`` meaning
decreasing away from the impact end): its values are then sorted, so every candidate is a
monotone profile.

The search works in the unit cube: every variable is one coordinate ``x`` in [0, 1]. Reals map
linearly onto ``[low, high]``; integers, catalogue sizes and categories split [0, 1] into equal
bins, one per allowed value (an ordinal encoding: neighbouring bins are neighbouring sizes).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any, Iterable, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict

from ..errors import ConfigError
from ..config import parse_path, set_path
from .catalogues import catalogue_sizes

__all__ = ["Variable", "Shape", "Space", "parse_variables"]

_SLICE = re.compile(r"^(?P<head>.*)\[(?P<start>\d+):(?P<stop>\d+)\]$")


def get_path(cfg: dict, tokens: list[str | int]) -> Any:
    """The value at ``tokens`` in ``cfg`` (KeyError/IndexError/TypeError when absent)."""
    node: Any = cfg
    for tok in tokens:
        node = node[tok]
    return node


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)

    low: float | None = None
    high: float | None = None
    integer: bool = False
    catalogue: str | list[float] | None = None
    choices: list[Any] | None = None
    monotone: bool | Literal["decreasing", "increasing"] = False


@dataclass(frozen=True)
class Variable:
    """One coordinate of the design space.

    Parameters
    ----------
    path : str
        Dotted path of the field it sets (``chain.diameters_mm[17]``, ``shape.exponent``).
    kind : {"real", "integer", "choice"}
        Real range, integer range, or a finite list of values (categories, catalogue sizes).
    low, high : float
        Range of a real or integer variable (inclusive).
    choices : tuple
        The allowed values of a ``"choice"`` variable, in order.
    group : str
        The path as the user wrote it (a list range ``chain.diameters_mm[16:30]`` is one group
        of several variables).
    """

    path: str
    kind: Literal["real", "integer", "choice"]
    low: float = 0.0
    high: float = 1.0
    choices: tuple = ()
    group: str = ""
    tokens: tuple = field(default=(), repr=False)

    @property
    def n_values(self) -> int:
        """Number of allowed values (0 for a real variable)."""
        if self.kind == "integer":
            return int(self.high - self.low) + 1
        return len(self.choices) if self.kind == "choice" else 0

    def decode(self, x: float) -> Any:
        """The value of unit-cube coordinate ``x`` (clipped to [0, 1])."""
        x = min(max(float(x), 0.0), 1.0)
        if self.kind == "real":
            return self.low + x * (self.high - self.low)
        m = self.n_values
        i = min(int(math.floor(x * m)), m - 1)
        return int(self.low) + i if self.kind == "integer" else self.choices[i]

    def bin_centre(self, x: float) -> float:
        """The centre of the bin holding ``x`` (``x`` itself for a real variable)."""
        if self.kind == "real":
            return min(max(float(x), 0.0), 1.0)
        m = self.n_values
        i = min(int(math.floor(min(max(x, 0.0), 1.0) * m)), m - 1)
        return (i + 0.5) / m


@dataclass(frozen=True)
class Shape:
    """A parametric chain shape appended after the base chain's beads (``[design.shape]``).

    With phi_0 the diameter of the base chain's last bead [mm], the ``n`` appended beads are

    - ``kind = "power"``: phi_k = phi_0 + (last_mm - phi_0) (k / n)^exponent, k = 1..n
      (``exponent = 1``: a linear taper; < 1 drops fast first, > 1 slowly first);
    - ``kind = "linear"``: the same with ``exponent = 1``;
    - ``kind = "decorated"``: ``n`` pairs (small bead, large bead) of ``small_mm`` and
      ``large_mm`` (default phi_0), the small beads of ``small_material`` (default: the chain's
      material): a chain decorated with interleaved small beads.

    The exponential taper of the paper (phi_{k+1} = (1 - q) phi_k) is the run config's own
    ``chain.taper = {n, q}``. Design variables address these parameters as ``shape.NAME``.
    """

    kind: Literal["linear", "power", "decorated"]
    params: dict

    def beads(self, phi0: float, material: str) -> tuple[list[float], list[str]]:
        """Diameters [mm] and materials of the appended beads."""
        p = self.params
        n = int(p["n"])
        if self.kind in ("linear", "power"):
            e = 1.0 if self.kind == "linear" else float(p.get("exponent", 1.0))
            last = float(p["last_mm"])
            d = [phi0 + (last - phi0) * (k / n) ** e for k in range(1, n + 1)]
            return d, [material] * n
        small, large = float(p["small_mm"]), float(p.get("large_mm", phi0))
        small_mat = str(p.get("small_material", material))
        return [small, large] * n, [small_mat, material] * n


_SHAPE_KEYS = {"linear": {"n", "last_mm"}, "power": {"n", "last_mm", "exponent"},
               "decorated": {"n", "small_mm", "large_mm", "small_material"}}
_SHAPE_REQUIRED = {"linear": {"n", "last_mm"}, "power": {"n", "last_mm"}, "decorated": {"n", "small_mm"}}


def parse_shape(data: dict | None) -> Shape | None:
    """Validate ``[design.shape]`` (None when absent)."""
    if data is None:
        return None
    if not isinstance(data, dict):
        raise ConfigError("design.shape", "must be a table such as { kind = \"power\", n = 14, last_mm = 11.0 }")
    kind = data.get("kind")
    if kind not in _SHAPE_KEYS:
        raise ConfigError("design.shape.kind", f"must be 'linear', 'power' or 'decorated', got {kind!r}")
    params = {k: v for k, v in data.items() if k != "kind"}
    for k in params:
        if k not in _SHAPE_KEYS[kind]:
            raise ConfigError(f"design.shape.{k}", f"unknown key for kind = '{kind}'; allowed: "
                              f"kind, {', '.join(sorted(_SHAPE_KEYS[kind]))}")
    for k in sorted(_SHAPE_REQUIRED[kind] - set(params)):
        raise ConfigError(f"design.shape.{k}", f"is required for kind = '{kind}' (a value, or a design variable "
                          f"'shape.{k}' with a placeholder value here)")
    return Shape(kind, params)


def _shape_value_error(shape: Shape, params: dict) -> None:
    n = params["n"]
    if not (isinstance(n, int) and not isinstance(n, bool) and n >= 1):
        raise ConfigError("design.shape.n", f"must be an integer >= 1, got {n!r}")
    for k in ("last_mm", "small_mm", "large_mm"):
        if k in params and not (isinstance(params[k], (int, float)) and params[k] > 0):
            raise ConfigError(f"design.shape.{k}", f"must be a positive diameter in mm, got {params[k]!r}")
    if "exponent" in params and not (isinstance(params["exponent"], (int, float)) and params["exponent"] > 0):
        raise ConfigError("design.shape.exponent", f"must be positive, got {params['exponent']!r}")


def _variable_field(path: str) -> str:
    return f'design.variables["{path}"]'


def parse_variables(spec: dict, base: dict, shape: Shape | None) -> tuple[list[Variable], dict[str, str]]:
    """Turn ``[design].variables`` into :class:`Variable` objects (a list range gives one per item).

    Returns the variables and ``{group path: "decreasing" | "increasing"}`` of the monotone ranges.

    Raises :class:`ConfigError` naming ``design.variables["PATH"]`` for a bad path or range.
    """
    if not isinstance(spec, dict) or not spec:
        raise ConfigError("design.variables", "needs at least one variable, e.g. { \"chain.taper.q\" = [0.0, 0.2] }")
    out: list[Variable] = []
    monotone_groups: dict[str, str] = {}
    for path, raw in spec.items():
        name = _variable_field(path)
        m = _SLICE.match(path)
        head = m.group("head") if m else path
        try:
            tokens = parse_path(head)
        except ValueError:
            raise ConfigError(name, "is not a dotted path into the base config (e.g. 'chain.taper.q', "
                              "'chain.diameters_mm[3]', 'chain.diameters_mm[16:30]', 'shape.exponent')") from None
        if tokens[0] == "shape":
            if shape is None:
                raise ConfigError(name, "addresses a chain shape, but [design.shape] is not given")
            if len(tokens) != 2 or tokens[1] not in _SHAPE_KEYS[shape.kind] or m:
                raise ConfigError(name, f"shape parameters of kind '{shape.kind}': "
                                  f"{', '.join('shape.' + k for k in sorted(_SHAPE_KEYS[shape.kind]))}")
        elif tokens[0] in ("run",) and len(tokens) > 1 and tokens[1] in ("duration", "sample_interval", "integrator"):
            raise ConfigError(name, "every candidate shares the run settings; set them in [base.run]")
        kind, low, high, choices, monotone = _parse_spec(raw, name)
        if m:
            start, stop = int(m.group("start")), int(m.group("stop"))
            try:
                seq = get_path(base, tokens)
            except (KeyError, IndexError, TypeError):
                seq = None
            if not isinstance(seq, list):
                raise ConfigError(name, f"a range of items needs the list '{head}' in [base]")
            if not (0 <= start < stop <= len(seq)):
                raise ConfigError(name, f"range [{start}:{stop}] must lie inside the base list (0..{len(seq)}) and "
                                  "hold at least one item")
            items: Iterable[int | None] = range(start, stop)
        else:
            if monotone:
                raise ConfigError(name, "monotone applies to a range of list items such as 'chain.diameters_mm[16:30]'")
            items = [None]
        for i in items:
            p = head if i is None else f"{head}[{i}]"
            toks = tuple(tokens) if i is None else (*tokens, i)
            out.append(Variable(p, kind, low, high, choices, path, toks))
        if monotone:
            monotone_groups[path] = "increasing" if monotone == "increasing" else "decreasing"
    return out, monotone_groups


def _parse_spec(raw: Any, name: str) -> tuple[Literal["real", "integer", "choice"], float, float, tuple, bool | str]:
    """(kind, low, high, choices, monotone) of one variable's spec."""
    def is_int(v: Any) -> bool:
        return isinstance(v, int) and not isinstance(v, bool)

    def is_num(v: Any) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

    if isinstance(raw, list):
        if raw and all(isinstance(v, str) for v in raw):
            return "choice", 0.0, 1.0, tuple(raw), False
        if len(raw) != 2 or not all(is_num(v) for v in raw):
            raise ConfigError(name, f"give [low, high] (two numbers), a list of names to choose from, or a table "
                              f"{{ low, high, integer, catalogue, choices, monotone }}, got {raw!r}")
        spec = _Spec(low=raw[0], high=raw[1], integer=is_int(raw[0]) and is_int(raw[1]))
    elif isinstance(raw, dict):
        from pydantic import ValidationError

        try:
            spec = _Spec.model_validate(raw)
        except ValidationError as exc:
            err = exc.errors()[0]
            where = ".".join(str(x) for x in err["loc"])
            if err["type"] == "extra_forbidden":
                raise ConfigError(f"{name}.{where}", "unknown key; allowed: low, high, integer, catalogue, choices, "
                                  "monotone") from None
            raise ConfigError(f"{name}.{where}" if where else name,
                              err["msg"].removeprefix("Value error, ") + f" (got {err.get('input')!r})") from None
    else:
        raise ConfigError(name, f"give [low, high], a list of names, or a table {{ low, high, ... }}, got {raw!r}")

    if spec.choices is not None:
        if not spec.choices:
            raise ConfigError(f"{name}.choices", "needs at least one value")
        if spec.low is not None or spec.high is not None or spec.catalogue is not None:
            raise ConfigError(name, "give either choices or a range (low, high), not both")
        return "choice", 0.0, 1.0, tuple(spec.choices), spec.monotone
    if spec.low is None or spec.high is None:
        raise ConfigError(name, "needs low and high (or choices)")
    if not (math.isfinite(spec.low) and math.isfinite(spec.high)):
        raise ConfigError(name, "low and high must be finite numbers")
    if spec.high < spec.low:
        raise ConfigError(name, f"high ({spec.high!r}) must not be below low ({spec.low!r})")
    if spec.catalogue is not None:
        sizes = catalogue_sizes(spec.catalogue, spec.low, spec.high, f"{name}.catalogue")
        return "choice", spec.low, spec.high, sizes, spec.monotone
    if spec.integer:
        lo, hi = math.ceil(spec.low), math.floor(spec.high)
        if lo > hi:
            raise ConfigError(name, f"holds no integer between {spec.low!r} and {spec.high!r}")
        return "integer", float(lo), float(hi), (), spec.monotone
    return "real", float(spec.low), float(spec.high), (), spec.monotone


def _set_own(cfg: dict, tokens: tuple, value: Any, copied: set[int], name: str) -> None:
    """Set ``value`` at ``tokens`` in ``cfg``, first replacing the tables and lists along the way
    by copies made for ``cfg`` (ids in ``copied``), so that the shared base is left untouched.
    Where the path leaves the config, ``set_path`` takes over: it creates missing tables or
    names what is wrong (``name``: the field as the user wrote it)."""
    node: Any = cfg
    for tok in tokens[:-1]:
        if type(node) is dict and type(tok) is str and tok in node:
            child = node[tok]
        elif type(node) is list and type(tok) is int and tok < len(node):
            child = node[tok]
        else:
            set_path(cfg, list(tokens), value, name)
            return
        if isinstance(child, (dict, list)) and id(child) not in copied:
            child = dict(child) if isinstance(child, dict) else list(child)
            copied.add(id(child))
            node[tok] = child
        node = child
    last = tokens[-1]
    if type(node) is dict and type(last) is str:
        node[last] = value
    elif type(node) is list and type(last) is int and last < len(node):
        node[last] = value
    else:
        set_path(cfg, list(tokens), value, name)


@dataclass
class Space:
    """Variables, monotone groups and the optional chain shape: decodes unit-cube points into run configs.

    Parameters
    ----------
    base : dict
        The base run config (``[base]``), as read from TOML.
    variables : list of Variable
        One per coordinate.
    shape : Shape or None
        Chain shape appended after the base chain (``[design.shape]``).
    monotone : dict
        ``{group path: "decreasing" | "increasing"}`` for list ranges kept monotone.
    """

    base: dict
    variables: list[Variable]
    shape: Shape | None = None
    monotone: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._by_group: dict[str, list[Variable]] = {}
        for v in self.variables:
            self._by_group.setdefault(v.group, []).append(v)

    @property
    def dim(self) -> int:
        """Number of coordinates."""
        return len(self.variables)

    @property
    def real(self) -> np.ndarray:
        """Mask of the real coordinates (the others are binned: integers, catalogue sizes, categories)."""
        return np.array([v.kind == "real" for v in self.variables])

    @property
    def groups(self) -> list[str]:
        """The variable paths as the user wrote them, in order."""
        return list(dict.fromkeys(v.group for v in self.variables))

    def values(self, x: np.ndarray) -> dict[str, Any]:
        """``{group path: value}`` of point ``x`` (a list for a list range), monotone groups sorted."""
        out: dict[str, Any] = {}
        for v, xi in zip(self.variables, x):
            val = v.decode(xi)
            if v.path != v.group:
                out.setdefault(v.group, []).append(val)
            else:
                out[v.group] = val
        for g, direction in self.monotone.items():
            out[g] = sorted(out[g], reverse=direction == "decreasing")
        return out

    def key(self, x: np.ndarray) -> tuple:
        """Hashable identity of the candidate ``x`` decodes to (equal keys: equal run configs)."""
        return self.key_of(self.values(x))

    @staticmethod
    def key_of(values: dict[str, Any]) -> tuple:
        """:meth:`key` of a candidate given by its ``{group path: value}``."""
        return tuple((g, tuple(v) if isinstance(v, list) else v) for g, v in values.items())

    def config(self, values: dict[str, Any]) -> dict:
        """The run config (mapping) of a candidate given by ``{group path: value}``.

        Tables and lists on a variable's path are copied; the rest is shared with ``base``
        (copy on write: a search builds thousands of these, and a deep copy of the base was
        most of the cost of a geometry check). Treat the result as read-only.
        """
        cfg = dict(self.base)
        copied: set[int] = set()
        shape_params = dict(self.shape.params) if self.shape is not None else {}
        by_group = self._by_group
        for g, val in values.items():
            vs = by_group[g]
            vals = val if vs[0].path != g else [val]
            for v, value in zip(vs, vals):
                if v.tokens[0] == "shape":
                    shape_params[v.tokens[1]] = value
                else:
                    _set_own(cfg, v.tokens, value, copied, _variable_field(g))
        if self.shape is not None:
            cfg = self._apply_shape(cfg, shape_params)
        return cfg

    def _apply_shape(self, cfg: dict, params: dict) -> dict:
        """Replace ``[chain]``'s bead list by the base beads followed by the shape's beads."""
        from ..config import build_chain, parse_config

        assert self.shape is not None  # (config() calls it for a shape only)
        _shape_value_error(self.shape, params)
        chain = build_chain(parse_config(cfg))
        names = [m.name for m in chain.materials]
        # Back to mm, rounded to 12 digits so that 26e-3 m is written as 26.0, not 26.000000000000004.
        d_mm = [float(f"{x * 1e3:.12g}") for x in chain.diameters]
        extra_d, extra_m = Shape(self.shape.kind, params).beads(d_mm[-1], names[-1])
        chain_cfg = {k: v for k, v in cfg["chain"].items()
                     if k not in ("diameters_mm", "preset", "uniform", "taper", "truncate", "materials", "substitutions",
                                  "offsets_mm", "offsets_fraction")}
        chain_cfg["diameters_mm"] = d_mm + extra_d
        mats = names + extra_m
        if len(set(mats)) > 1:
            chain_cfg["materials"] = mats
        else:
            chain_cfg["material"] = mats[0]
        offsets = [float(f"{x * 1e3:.12g}") for x in chain.offsets]
        if any(offsets):
            chain_cfg["offsets_mm"] = offsets + [0.0] * len(extra_d)
        return {**cfg, "chain": chain_cfg}

    def decode(self, x: np.ndarray) -> tuple[dict[str, Any], dict]:
        """``(values, run config)`` of unit-cube point ``x``."""
        vals = self.values(x)
        return vals, self.config(vals)

    def centre(self, x: np.ndarray) -> np.ndarray:
        """``x`` with every discrete coordinate moved to the centre of its bin."""
        return np.array([v.bin_centre(xi) for v, xi in zip(self.variables, x)])
