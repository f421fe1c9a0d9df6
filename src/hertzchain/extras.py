"""Optional dependencies: the named extras of ``pip install 'hertzchain[EXTRA]'`` and the one
clean error when a feature's extra is missing.

The core install carries what ``run``, ``plot``, ``analyze`` and ``reproduce`` need; a feature
beyond them imports its packages where it runs, after :func:`require` has checked them, so a
missing extra ends in one paragraph naming it (exit status 2 on the command line), never an
ImportError half-way through a job.
"""

from __future__ import annotations

import importlib

from .errors import ConfigError

__all__ = ["EXTRAS", "require"]

#: What each extra is for, and the modules it provides (pyproject.toml's optional dependencies).
EXTRAS = {
    "cluster": ("Dask worker processes here or on other machines (--scheduler)", ("distributed",)),
    "design": ("the design search (CMA-ES; NSGA-II; best.toml)", ("cma", "tomli_w")),
    "lab": ("writing the fitted model as a run config (fit.toml)", ("tomli_w",)),
    "explore": ("the interactive explorer (Panel on Bokeh)", ("panel", "bokeh")),
    "export": ("parquet files (pyarrow)", ("pyarrow",)),
}


def _importable(module: str) -> bool:
    try:
        importlib.import_module(module)  # the feature imports it next anyway
    except ImportError:
        return False
    return True


def require(extra: str, field: str, modules: tuple[str, ...] | None = None) -> None:
    """Check that the packages of ``extra`` can be imported, before any work.

    Parameters
    ----------
    extra : str
        A key of :data:`EXTRAS` (``"cluster"``, ``"design"``...).
    field : str
        What asked for it, named by the error (``"--scheduler"``, ``"design"``).
    modules : tuple of str, optional
        The modules this feature needs; default: every module of the extra.

    Raises
    ------
    ConfigError
        A module is missing: ``needs X: pip install 'hertzchain[EXTRA]'``.
    """
    what, provided = EXTRAS[extra]
    missing = [m for m in (modules or provided) if not _importable(m)]
    if missing:
        raise ConfigError(field, f"needs {', '.join(missing)} for {what}: pip install 'hertzchain[{extra}]' "
                          f"(or pip install -e '.[{extra}]' in a clone)")
