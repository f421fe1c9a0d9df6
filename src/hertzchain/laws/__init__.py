"""Contact laws: the protocol (:class:`LawSpec`) and the registry every part of the package asks.

Built-in laws register in :mod:`hertzchain.laws.builtin`; a user's law registers the same way
(:func:`register_law`, docs/guide/laws.rst). Nothing outside this package compares a law's
name: it asks its spec (``spec_of(law).dissipative``, ``.plastic``, ``.calibrated`` ...).
"""

from .spec import (FIRST_GENERATED_CODE, LawSpec, Param, get_law, hertz_equivalent, is_conservative, is_plastic, jit,
                   law_names, law_of_code, register_law, spec_of)
from . import builtin  # noqa: E402,F401  (registers the built-in laws; spec.py itself imports none of them)

__all__ = ["LawSpec", "Param", "register_law", "get_law", "law_names", "law_of_code", "spec_of",
           "FIRST_GENERATED_CODE", "hertz_equivalent", "is_conservative", "is_plastic", "jit", "PowerLaw", "HuntCrossley", "load_law_file"]


def __getattr__(name):
    if name == "PowerLaw":
        from .power import PowerLaw
        return PowerLaw
    if name == "HuntCrossley":
        from .hunt_crossley import HuntCrossley
        return HuntCrossley
    raise AttributeError(name)


def load_law_file(path) -> list[str]:
    """Run a user's law file (Python that calls :func:`register_law`) and return the names it registered.

    Called by the CLI's ``--laws FILE`` only: a config never names code to run.
    """
    import runpy
    from pathlib import Path

    from ..errors import ConfigError

    p = Path(path)
    if not p.is_file() or p.suffix != ".py":
        raise ConfigError("--laws", f"must name an existing Python file (.py), got {str(path)!r}")
    before = set(law_names())
    try:
        runpy.run_path(str(p), run_name=f"hertzchain_user_laws_{p.stem}")
    except ConfigError:
        raise
    except Exception as exc:  # the user's code: report it as an input error, no traceback
        raise ConfigError("--laws", f"{p}: {type(exc).__name__}: {exc}") from exc
    return [n for n in law_names() if n not in before]
