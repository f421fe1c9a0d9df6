"""The contact-law figure of the reproduction: F_m and tau along both chains under each law.

:func:`fig_laws` draws ``summary["fidelity"]["laws"]`` (see
:func:`hertzchain.paper.fidelity.law_numbers`) with the ballistic predictions of eqs. 7-8. It
needs no trace nor fit, only NumPy, Matplotlib and :mod:`hertzchain.theory`, so that
:mod:`hertzchain.paper.early` can draw it while the analysis stack is still being imported;
:mod:`hertzchain.paper.fidelity` re-exports it.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from .. import theory
from .values import PAPER

__all__ = ["LAW_STYLE", "fig_laws"]

#: Marker, colour and label of each contact law in :func:`fig_laws`.
LAW_STYLE = {"elastic": ("s", "0.45", "elastic"), "viscoelastic": ("o", "#1f77b4", "Kuwabara-Kono, constant A"),
             "viscoelastic_scaled": ("^", "#d62728", "Kuwabara-Kono, A ~ collision time"),
             "viscoelastic_sized": ("v", "#9467bd", "Kuwabara-Kono, A ~ collision time^2"),
             "dashpot_scaled": ("D", "#2ca02c", "dashpot, gamma ~ kappa^(2/5) mu^(3/5)")}


def fig_laws(numbers: dict, eps: float = PAPER["eps"]) -> Figure:
    """F_m(n)/F_m(16) and tau(n)/tau(16) along both chains under each contact law, with eqs. 7-8.

    Top: peak wall force of the chain truncated after bead n over that of the uniform part
    (n = 16), for the elastic, constant-A and size-scaled laws (markers), with eq. 7 for the
    chain's q and eps = 1 (dotted), q and ``eps`` (solid) and q = 0, ``eps`` (dashed, dissipation
    alone). Bottom: the same for the duration tau with eq. 8 (tau_n = (phi_n/2) sqrt(10) / v_n,
    with the chain's real diameters phi_n in every curve: the dashed one is the wave speed of
    q = 0 with those diameters, not a uniform chain, and says so in the legend). One legend below
    the panels, clear of the data.

    Parameters
    ----------
    numbers : dict
        :func:`hertzchain.paper.fidelity.law_numbers` output (``summary["fidelity"]["laws"]``).
    eps : float
        eps of the dissipative predictions.

    Returns
    -------
    matplotlib.figure.Figure
        2 x 2 panels (force, duration; chain 1, chain 2).
    """
    import matplotlib
    from matplotlib.lines import Line2D
    from matplotlib.ticker import MaxNLocator

    from ..viz.style import STYLE, paper_figure

    with matplotlib.rc_context(STYLE):
        fig = paper_figure(7.0, 4.8)
        axes = fig.subplots(2, 2, sharex="col")
        for col, chain in enumerate(("chain1", "chain2")):
            any_row = next(iter(numbers.values()))[chain]
            beads = np.asarray(any_row["beads"])
            n0 = int(beads[0])
            q = theory.tapering_factor(np.asarray(theory.PAPER_CHAINS[chain]) * 1e-3, n0)[0]
            phi = np.asarray(theory.PAPER_CHAINS[chain], dtype=float)[beads - 1]
            for law, row in numbers.items():
                marker, colour, label = LAW_STYLE.get(law, ("x", "k", law))
                c = row[chain]
                F, tau = np.asarray(c["peak_force"]), np.asarray(c["duration"])
                axes[0, col].plot(beads, F / F[0], marker, color=colour, mfc="none", label=label)
                axes[1, col].plot(beads, tau / tau[0], marker, color=colour, mfc="none", label=label)
            k = beads - n0
            for e, qq, ls in ((1.0, q, ":"), (eps, q, "-"), (eps, 0.0, "--")):
                r = theory.ballistic_ratios(qq, e)
                axes[0, col].plot(beads, r.force ** k, color="k", ls=ls, lw=0.8)
                # tau_n = (phi_n / 2) sqrt(10) / v_n with the real phi_n, v_n from eq. 8 with this q
                axes[1, col].plot(beads, phi / phi[0] / r.speed ** k, color="k", ls=ls, lw=0.8)
            axes[0, col].set_title(f"chain {chain[-1]} (q = {100 * q:.2f} %)")
            axes[0, col].set_ylabel(f"$F_m(n) / F_m({n0})$")
            axes[1, col].set_ylabel(f"$\\tau(n) / \\tau({n0})$")
            axes[1, col].set_xlabel("bead n (chain truncated after n)")
            axes[1, col].xaxis.set_major_locator(MaxNLocator(integer=True))
        handles = [Line2D([], [], ls="none", marker=LAW_STYLE.get(law, ("x", "k", law))[0], mfc="none",
                          color=LAW_STYLE.get(law, ("x", "k", law))[1], label=LAW_STYLE.get(law, ("x", "k", law))[2])
                   for law in numbers]
        handles += [Line2D([], [], color="k", ls=ls, lw=0.8, label=lab) for ls, lab in (
            (":", "eqs. 7-8 with the chain's q, eps = 1"), ("-", f"eqs. 7-8 with the chain's q, eps = {eps:g}"),
            ("--", f"eq. 7 with q = 0, eps = {eps:g} (dissipation alone); eq. 8: the speeds of q = 0 "
                   "with the real diameters"))]
        # below the panels (constrained layout makes room): inside, it covered data markers
        fig.legend(handles=handles, loc="outside lower center", ncol=2, fontsize=6, frameon=False)
    return fig
