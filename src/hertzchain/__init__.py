"""hertzchain: impulse propagation in chains of elastic beads with Hertz contacts."""

from __future__ import annotations

__version__ = "0.1.0"

from .errors import ConfigError, ElasticLimitWarning, HertzchainError, PulseNotFound, SimulationDiverged
from .materials import CATALOGUE, Material, get_material, register_material
from .contact import Dashpot, Elastic, Viscoelastic, hertz_constant, yield_force
