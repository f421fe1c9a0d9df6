"""Run configuration (TOML): schema, validation and translation into model objects.

Validation uses pydantic in strict mode; every problem is reported as a
:class:`~hertzchain.errors.ConfigError` naming the field as the user wrote it
(``chain.diameters_mm[3]``, ``chain.uniform.diameter_mm``), what was wrong and what is allowed.
Types are strict (``true`` or ``"0.5"`` is not a number, ``1.0`` is not a bead count) and every
number has physical bounds (:data:`BOUNDS`), so values such as 1e300 or 1e-300 are refused before
they reach the engine. Keys that take non-SI units say so in their name (``diameter_mm``); all
others are SI.

A minimal config (the contract of the core-engine issue)::

    [chain]
    material = "AISI52100"
    diameters_mm = [26, 26, 26, 24, 23, 22]
    [striker]
    diameter_mm = 8.0
    velocity = 0.5          # m/s
    [wall]
    type = "flat"           # or "none"
    [run]
    duration = 2.5e-3       # s, or "auto" (the default)
    sample_interval = 1e-7  # s
    [probes]
    sensors = [2]

The package has three parts: :mod:`~hertzchain.config.schema` (the sections and their bounds,
:func:`parse_config`), :mod:`~hertzchain.config.loading` (reading TOML, dotted paths and ``--set``
overrides, :func:`load_config`) and :mod:`~hertzchain.config.build` (the model, probes,
instruments and track of a config, and running it: :func:`build_model`, :func:`run_config`).
"""

from __future__ import annotations

# Every name below stays importable from hertzchain.config, where the rest of the package and
# users import it; __all__ lists the documented API.
from .build import (MAX_SCOPE_SAMPLES, apply_instruments, build_chain, build_instruments, build_model, build_probes,
                    build_track, chain_of, chain_parts, preflight_run, run_config, simulate_config)
from .loading import apply_overrides, load_config, parse_path, read_toml, set_path
from .schema import (BOUNDS, ChainConfig, ContactConfig, InstrumentChannel, InstrumentConfig, MaterialConfig,
                     ProbesConfig, RunConfig, RunSection, StrikerConfig, Substitution, TaperBlock, TrackConfig,
                     UniformBlock, WallConfig, parse_config)

__all__ = ["RunConfig", "load_config", "parse_config", "build_model", "build_probes", "run_config"]
