"""The paper's own values, so that every simulated number can stand beside the measured one.

All from Melo et al., PRE 2006: Sec. II (material, yield, tapering factors, wall/chain ratios from
Job et al. 2005) and Sec. III (eps, Q_1, Q_2 and their theoretical values).
"""

from __future__ import annotations

from typing import Any

#: Per chain (and for the material and the protocol): named values, numbers, lists or text.
PAPER: dict[str, Any] = {
    "chain1": {"q": 0.0560, "q_std": 0.0067, "Q_fit": 1.025, "Q_fit_err": 0.016, "Q_theory": 1.014,
               "n_beads": 30},
    "chain2": {"q": 0.0827, "q_std": 0.0031, "Q_fit": 1.049, "Q_fit_err": 0.044, "Q_theory": 1.022,
               "n_beads": 28},
    "eps": 0.985,
    "wall_to_chain_force_ratio": 1.94,
    "wall_to_chain_duration_ratio": 1.09,
    "yield_force": 470.0,        # N, 26 mm AISI 52100 beads
    "yield_overlap": 11e-6,      # m
    "n0": 16,
    "striker_diameter": 8e-3,    # m
    "bead_diameter": 26e-3,      # m
}

#: Beads whose wall pulses the paper shows in Figs. 1-2 (b)-(g).
FIG12_TRUNCATIONS = (18, 20, 22, 24, 26, 28)
