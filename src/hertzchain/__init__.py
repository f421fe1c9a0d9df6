"""hertzchain: impulse propagation in chains of elastic beads with Hertz contacts.

The public API is re-exported here and loaded lazily (PEP 562), so ``import hertzchain`` and the
CLI's ``--help`` stay fast; the compiled kernels load on first use.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

_EXPORTS = {
    # errors
    "HertzchainError": "errors", "ConfigError": "errors", "SimulationDiverged": "errors",
    "PulseNotFound": "errors", "PulseClipped": "errors", "ElasticLimitWarning": "errors", "HertzRangeWarning": "errors",
    "PulseNotReachedWarning": "errors", "LongRunWarning": "errors", "CheckpointWarning": "errors",
    # checks
    "estimate_resources": "checks", "ResourceEstimate": "checks",
    # model
    "Material": "materials", "CATALOGUE": "materials", "get_material": "materials",
    "register_material": "materials",
    "Elastic": "contact", "Viscoelastic": "contact", "ScaledViscoelastic": "contact", "Dashpot": "contact", "hertz_constant": "contact",
    "ScaledDashpot": "contact", "SizedViscoelastic": "contact", "Elastoplastic": "plasticity",
    "PowerLaw": "laws.power", "HuntCrossley": "laws.hunt_crossley", "register_law": "laws", "LawSpec": "laws",
    "Param": "laws", "get_law": "laws",
    "yield_force": "contact",
    "Chain": "chain", "paper_chain": "chain", "TABLE_I_MM": "chain", "Element": "elements",
    "Striker": "model", "Wall": "model", "Model": "model",
    # lateral freedom (the 2D path)
    "Track": "runs.track", "simulate_lateral": "runs.track",
    # running and results
    "Probes": "probes", "simulate": "runs.simulation", "auto_duration": "runs.simulation", "save": "result", "load": "result",
    "export": "exporting",
    "load_config": "config.loading", "parse_config": "config.schema", "run_config": "config.build",
    "build_model": "config.build",
    # many chains
    "simulate_batch": "runs.batch", "simulate_many": "runs.batch", "Ensemble": "integrate.batch.ensemble",
    "run_sweep": "sweep.runner", "load_sweep": "sweep.schema",
    # design search
    "load_design": "design", "parse_design": "design", "run_design": "design", "write_report": "design",
    "DesignProblem": "design", "DesignResult": "design",
    # sensitivities (exact derivatives of results by config fields)
    "sensitivity": "gradients", "Sensitivity": "gradients", "trace_sensitivity": "gradients",
    # dissipation
    "calibrate_law": "dissipation", "measure_eps": "dissipation", "restitution": "collision",
    # measurement, analysis, theory
    "Instrument": "instrument", "sensor_wall": "instrument",
    "fit_pulse": "analysis", "PulseFit": "analysis", "power_spectrum": "analysis",
    # laboratory data: scope files, comparison, calibration
    "read_trace": "lab", "compare_traces": "lab", "Comparison": "lab", "fit_traces": "lab", "Trace": "lab",
    "FitResult": "lab",
    "tapering_factor": "theory", "ballistic_ratios": "theory", "solitary_wave_speed": "theory",
    "yield_limit": "theory", "predict_chain": "theory", "nesterenko_force": "theory",
    # granular crystals: statics, modes, band structure, drives, transmission
    "equilibrium": "crystal.statics", "Equilibrium": "crystal.statics", "modes": "crystal.modes",
    "Modes": "crystal.modes", "dispersion": "crystal.dispersion", "Drive": "crystal.drive",
    "transmission_spectrum": "crystal.spectrum",
    "transmission_against_amplitude": "crystal.spectrum", "linear_transmission": "crystal.modes",
    # pictures of results and sweeps
    "plot_signals": "viz.signals", "plot_spacetime": "viz.spacetime", "plot_energy": "viz.energy",
    "animate": "viz.animation", "plot_metrics": "viz.metrics", "plot_ensemble": "viz.ensemble",
    "plot_sensitivity": "viz.sensitivity",
    # the interactive explorer (Panel; the [explore] extra)
    "explore": "explorer",
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'hertzchain' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
