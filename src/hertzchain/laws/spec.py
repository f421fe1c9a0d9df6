"""The contact-law protocol and its registry.

A law declares itself once, in a :class:`LawSpec`: its config name, its parameters
(:class:`Param`: name, unit, bounds, default; the one source of the config schema's checks, the
strict Python API's checks and the docs table), the size of its per-contact state, and scalar
Numba-compiled functions of one contact (unit-free SI floats):

- ``force(d, rate, k, p, s)``: the force [N] at overlap ``d`` >= 0 [m] and overlap rate
  ``rate`` = d(delta)/dt [m/s], with the contact's stiffness ``k`` (N/m^n), its parameter ``p``
  (the law's per-contact number, e.g. the exponent) and its state ``s``; the engines clip it at
  zero (never attractive);
- ``state(d, rate, k, p, s)``: the new state after a force evaluation (``d`` < 0: the contact is
  open); laws without state return ``s``;
- ``energy(d, k, p)``: the elastic energy stored at overlap ``d`` [J] (the potential of the
  force at zero rate);
- ``partials(d, rate, k, p, s)``: (dF/d delta, dF/d rate, dF/dk, dF/dp), analytic, checked
  against central differences in tests/test_laws.py;
- optionally ``overlap_at_energy(e, k, p)``: the overlap [m] storing the energy ``e`` [J] (the
  inverse of ``energy``; the engines' step bound); without it the engine bisects ``energy``;
- for a law with state, ``state_partials(d, rate, k, p, s)``: (dF/ds, ds'/d delta, ds'/d rate,
  ds'/dk, ds'/dp, ds'/ds) with s' = ``state(d, rate, k, p, s)`` and dF/ds the force's partial at
  state s: what the sensitivity engines (:mod:`hertzchain.integrate.derivatives.law_derivatives`) need
  besides ``partials`` to carry derivatives through the state; without it a stateful law runs
  but has no sensitivities (refused naming ``contact.law``).

Built-in laws whose engines are hand-written (``generated=False``) keep integer codes 0..3 (the
kernels' ``LAW_*``); every other law is run by the engines generated from these functions
(:mod:`hertzchain.integrate.core.generated`) and gets a code from :data:`FIRST_GENERATED_CODE` on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol

from ..errors import ConfigError

#: Codes from this one on are run by the generated engines (4, 5: the built-in power and
#: Hunt-Crossley laws; users' laws from :data:`FIRST_USER_CODE` on, in the order registered).
FIRST_GENERATED_CODE = 4
FIRST_USER_CODE = 16


@dataclass(frozen=True)
class Param:
    """One parameter of a law as the config and the Python API take it.

    Parameters
    ----------
    name : str
        Its config key (``[contact] name = ...``) and attribute of the law object.
    unit : str
        Its unit ("s", "N s/m", "-").
    description : str
        What it is, in a few words (the docs table).
    low, high : float
        Bounds, inclusive unless ``open_low``/``open_high``.
    open_low, open_high : bool
        Exclusive bounds.
    default : float or None
        The value when not given; None: required unless ``optional``.
    optional : bool
        May be left out (the law has a documented fallback, e.g. the power law's stiffness).
    """

    name: str
    unit: str
    description: str
    low: float = -math.inf
    high: float = math.inf
    open_low: bool = False
    open_high: bool = False
    default: float | None = None
    optional: bool = False

    def check(self, value: Any, field_prefix: str = "contact") -> float | None:
        """The value as a float, or a :class:`ConfigError` naming ``contact.<name>``."""
        where = f"{field_prefix}.{self.name}"
        if value is None:
            if self.default is not None or self.optional:
                return self.default
            raise ConfigError(where, f"is required ({self.unit}: {self.description})")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(where, f"must be a number ({self.unit}), got {value!r}")
        x = float(value)
        lo_ok = x > self.low if self.open_low else x >= self.low
        hi_ok = x < self.high if self.open_high else x <= self.high
        if not (math.isfinite(x) and lo_ok and hi_ok):
            lo = "(" if self.open_low else "["
            hi = ")" if self.open_high else "]"
            raise ConfigError(where, f"must be in {lo}{self.low:g}, {self.high:g}{hi} ({self.unit}), got {value!r}")
        return x


class LazyJit:
    """A law function compiled with ``numba.njit(cache=True)`` on its first use.

    Declaring a law must not load Numba: the registry is read while a config is validated and by
    the closed forms of :mod:`hertzchain.theory`, which refuse or draw before anything compiles.
    Calling it from Python compiles it; engines take :attr:`dispatcher` (or ``py_func`` for CUDA).
    """

    def __init__(self, fn: Callable) -> None:
        self.py_func = fn
        self._dispatcher: Any = None
        self.__name__ = getattr(fn, "__name__", "law_function")
        self.__doc__ = fn.__doc__

    @property
    def dispatcher(self) -> Any:
        """The Numba dispatcher (compiled on first call, cached on disk)."""
        if self._dispatcher is None:
            from numba import njit

            self._dispatcher = njit(cache=True)(self.py_func)
        return self._dispatcher

    def __call__(self, *args):
        return self.dispatcher(*args)


def jit(fn: Callable) -> LazyJit:
    """Decorator of a law's scalar functions: ``numba.njit(cache=True)``, deferred to first use."""
    return LazyJit(fn)


def compiled(fn: Any) -> Any:
    """The Numba dispatcher of a law function declared with :func:`jit` or with ``numba.njit``."""
    return fn.dispatcher if isinstance(fn, LazyJit) else fn


class LawObject(Protocol):
    """What the package reads of every law object (a built-in one, PowerLaw, HuntCrossley, a user's):
    ``name``, its registered law, and ``parameter``, its scalar parameter. Anything else (a
    size-scaled law's ``contact_damping``, a law's own ``contact_stiffness``) is looked up with
    ``hasattr``."""

    @property
    def name(self) -> str: ...

    @property
    def parameter(self) -> float: ...


@dataclass(frozen=True)
class LawSpec:
    """A contact law declared once (see the module docstring).

    Parameters
    ----------
    name : str
        Its config name (``[contact] law``) and the ``name`` attribute of its law objects.
    title : str
        Its form in words (the docs table).
    params : tuple of Param
        Its parameters.
    state_size : int
        Floats of per-contact state (0 or 1 for a generated law).
    force, state, energy, partials : numba dispatcher
        The scalar functions of one contact (module docstring).
    overlap_at_energy : numba dispatcher, optional
        The inverse of ``energy`` (else bisected).
    state_partials : numba dispatcher, optional
        Derivatives through the state (module docstring); a law with state needs it for
        sensitivities.
    make : callable
        ``make(params, chain=None)``: the law object from its checked parameters (a dict name ->
        float or None) and, for size-scaled laws, the chain.
    dissipative, plastic : bool
        What the package asks of a law instead of comparing names.
    calibrated : str or None
        The parameter a target ``eps`` calibrates (None: not calibrated).
    generated : bool
        Run by the engines generated from the functions (False: the built-in hand-written ones).
    code : int
        Engine code (-1: assigned by :func:`register_law`).
    exponent : float or None
        The force's power of the overlap at zero rate when it is a fixed number (Hertz: 1.5).
    constant_parameters : tuple of float
        Values of the parameter for which the generated loops also compile the law with the
        parameter as a constant, used on aligned chains whose contacts all have one of them: the
        law's branches on its parameter fold and its arithmetic simplifies (the power law's
        n = 3/2: d sqrt(d); n = 2, a cone: d**2 -> d d, no pow), where a run-time branch costs
        every contact both sides once the loop is vectorised. Each value adds a loop to compile.
    hertz_parameter : float or None
        The parameter at which the law is the elastic law, F = k delta^(3/2) (paper eq. 1) with the
        contact's own k, without state or dissipation (the power law: n = 3/2); None: no such value.
        A chain whose every contact has it is run by the elastic law's own fourth-order engine
        (:func:`hertz_equivalent`), so that it gives the elastic run's numbers there too.
    extra : dict
        Anything else (``scaled``: a size-scaled built-in law).
    """

    name: str
    title: str
    params: tuple[Param, ...] = ()
    state_size: int = 0
    force: Callable | None = None
    state: Callable | None = None
    energy: Callable | None = None
    partials: Callable | None = None
    overlap_at_energy: Callable | None = None
    state_partials: Callable | None = None
    make: Callable[..., Any] | None = None
    dissipative: bool = False
    plastic: bool = False
    calibrated: str | None = None
    generated: bool = True
    code: int = -1
    #: the force's power of the overlap at zero rate (Hertz: 1.5) when it is a fixed number
    exponent: float | None = 1.5
    constant_parameters: tuple[float, ...] = ()
    hertz_parameter: float | None = None
    extra: dict = field(default_factory=dict)

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    def param(self, name: str) -> Param:
        """The parameter called ``name``."""
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(name)


_REGISTRY: dict[str, LawSpec] = {}
_BY_CODE: dict[int, LawSpec] = {}


def register_law(spec: LawSpec, *, replace: bool = False) -> LawSpec:
    """Register ``spec`` under its name and return it with its code.

    Parameters
    ----------
    spec : LawSpec
        The declaration. A generated law (the usual case for a user's law) needs ``force``,
        ``state``, ``energy`` and ``partials`` compiled with ``numba.njit`` (or declared with
        :func:`jit`, which compiles on first use); it gets the next free
        code.
    replace : bool
        Replace a law of that name (re-running a user's law file in one session); else refused.

    Returns
    -------
    LawSpec
        The registered declaration, with its engine code.
    """
    if not isinstance(spec, LawSpec):
        raise TypeError(f"register_law takes a LawSpec, got {type(spec).__name__}")
    if not spec.name.isidentifier():
        raise ConfigError("contact.law", f"a law's name must be an identifier, got {spec.name!r}")
    old = _REGISTRY.get(spec.name)
    if old is not None and not replace:
        raise ConfigError("contact.law", f"a law named {spec.name!r} is already registered")
    if spec.generated:
        missing = [f for f in ("force", "state", "energy", "partials") if getattr(spec, f) is None]
        if missing:
            raise ConfigError("contact.law", f"law {spec.name!r} needs compiled {', '.join(missing)} functions")
        code = old.code if old is not None else spec.code if spec.code >= 0 else max([FIRST_USER_CODE - 1, *_BY_CODE]) + 1
    else:
        code = spec.code
    spec = _with_code(spec, code)
    _REGISTRY[spec.name] = spec
    _BY_CODE.setdefault(code, spec)
    if old is not None and spec.generated:
        _BY_CODE[code] = spec
    return spec


def _with_code(spec: LawSpec, code: int) -> LawSpec:
    from dataclasses import replace as _replace

    return _replace(spec, code=code)


def get_law(name: str) -> LawSpec:
    """The registered law called ``name``.

    Parameters
    ----------
    name : str
        A law's config name.

    Returns
    -------
    LawSpec
        Its declaration; a :class:`ConfigError` naming ``contact.law`` (listing the registered
        laws) when there is none.
    """
    spec = _REGISTRY.get(name)
    if spec is None:
        raise ConfigError("contact.law", f"unknown law {name!r}; registered laws: {', '.join(law_names())} "
                                         "(a law of your own: hertzchain.register_law, or --laws FILE on the command line)")
    return spec


def law_names() -> tuple[str, ...]:
    """Names of every registered law, built-in ones first."""
    return tuple(_REGISTRY)


def hertz_equivalent(system) -> bool:
    """True where ``system`` (a :class:`hertzchain.model.System`) runs a registry law at its
    :attr:`LawSpec.hertz_parameter` on every contact: the elastic law F = kappa_j delta^(3/2)
    (paper eq. 1) in another name (the power law at n = 3/2), which the elastic law's own engines
    may run."""
    spec = law_of_code(system.law)
    if not spec.generated or spec.hertz_parameter is None or spec.state_size:
        return False
    loaded = system.kappa > 0
    return bool((system.damping[loaded] == spec.hertz_parameter).all())


def law_of_code(code: int) -> LawSpec:
    """The law an engine code stands for (the first name registered with it)."""
    return _BY_CODE[int(code)]


def spec_of(law: Any) -> LawSpec:
    """The spec of a law object (anything with a registered ``name``) or of a law name."""
    return get_law(law if isinstance(law, str) else getattr(law, "name", repr(law)))


def is_conservative(name) -> bool:
    """True when ``name`` is a registered law without dissipation (False for anything else, e.g.
    a name read from a file that this session does not know)."""
    spec = _REGISTRY.get(name) if isinstance(name, str) else None
    return spec is not None and not spec.dissipative


def is_plastic(name) -> bool:
    """True when ``name`` is a registered law that models yield (False for anything else)."""
    spec = _REGISTRY.get(name) if isinstance(name, str) else None
    return spec is not None and spec.plastic


def attach_maker(name: str, make: Callable[..., Any]) -> None:
    """Give the registered law ``name`` its constructor ``make(params, chain=None)`` (for laws whose
    classes live outside this package: the built-in ones in ``contact`` and ``plasticity``)."""
    from dataclasses import replace as _replace

    spec = _replace(_REGISTRY[name], make=make)
    _REGISTRY[name] = spec
    if _BY_CODE.get(spec.code) is not None and _BY_CODE[spec.code].name == name:
        _BY_CODE[spec.code] = spec
