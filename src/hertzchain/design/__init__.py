"""Design search: optimise chains against a goal under constraints (``hertzchain design``).

- :mod:`~hertzchain.design.space`: variables by dotted path, list ranges, catalogues, monotone
  profiles, materials, chain shapes;
- :mod:`~hertzchain.design.constraints`: geometry and run constraints;
- :mod:`~hertzchain.design.objectives`: objectives, robust forms, batched evaluation;
- :mod:`~hertzchain.design.search`: CMA-ES / NSGA-II, local polish, verification at full accuracy;
- :mod:`~hertzchain.design.boundary`: candidates past a geometric limit moved onto it;
- :mod:`~hertzchain.design.checkpoint`: the search state saved and safely read back;
- :mod:`~hertzchain.design.report`: best.toml, design.json, history.csv, pareto.csv, design.html.
"""

from __future__ import annotations

from .catalogues import CATALOGUES
from .problem import DesignProblem, load_design, parse_design
from .report import write_report
from .search import DesignResult, run_design

__all__ = ["CATALOGUES", "DesignProblem", "DesignResult", "load_design", "parse_design", "run_design",
           "write_report"]
