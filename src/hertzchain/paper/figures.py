"""The paper's six figures, drawn from the data of :mod:`hertzchain.paper.protocol`.

One function per figure of Melo, Job, Santibanez, Tapia, PRE 2006; each takes data objects
(:class:`~hertzchain.paper.protocol.ChainStudy`, the dicts of datasets returned by
``run_misalignment`` / ``run_substitutions``, the :class:`~.protocol.Settings`) and returns a
:class:`matplotlib.figure.Figure`; nothing here runs a simulation.

- :func:`fig1`, :func:`fig2`: pulse in the uniform part, wall force of the chains truncated after
  beads 18..28, power spectra of the incoming and outgoing pulses (chains 1 and 2);
- :func:`fig3`: misalignment of bead 22 and bead 28 of chain 2, single-bead substitutions in
  chain 1 cut after bead 24;
- :func:`fig4`: the self-similar collapse F/F_m against (t - T)/tau;
- :func:`fig5`: diameters, F_m, tau, Q_F and Q_T against the bead number, with eqs. 7-8;
- :func:`fig6`: time of flight, its departure from the restitution-only prediction, local speed.

:func:`figure_summary` gives the numbers the figures show (spectral centroids, misalignment and
substitution effects, collapse quality) so that the report can state them in words, and
:func:`save_figure` writes a figure as PNG (200 dpi) and PDF (vector).

Figures are built on ``Figure`` objects with the Agg canvas attached, so the global pyplot state
and the session's backend are never touched. Sizes follow the paper's two-column format
(~3.4 in a column, ~7 in a full width) with 8-pt fonts.

Conventions (SI inside, display units on the axes): forces in N, times in ms (pulse durations
in us), diameters in mm, momenta in mN s, speeds in m/s. Bead n is the paper's numbering (1 at
the impact end); "truncation n" is the chain cut after bead n with the wall behind it.
"""

from __future__ import annotations

import math

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from .. import analysis, theory
from ..viz.style import C1, C2, C3, CK, STYLE, paper_figure, panel_tag, save_figure, styled
from .values import FIG12_TRUNCATIONS, PAPER

__all__ = ["fig1", "fig2", "fig3", "fig4", "fig5", "fig6", "save_figure", "figure_summary",
           "STYLE", "PULSE_WINDOW_MS", "SPECTRUM_WINDOW_S", "SENSOR_BEAD"]

N0 = PAPER["n0"]

#: Shown range of t - T [ms] around each pulse's time of flight (Figs. 1-3).
PULSE_WINDOW_MS = (-0.4, 0.6)
#: Record cut for the power spectra [s]: T - 0.6 ms .. T + 0.6 ms, Hann-windowed around T.
SPECTRUM_WINDOW_S = (-0.6e-3, 0.6e-3)
#: Level (fraction of the maximum; 1e-2 = -20 dB) of the spectral bandwidth quoted in Figs. 1h-2h.
BANDWIDTH_LEVEL = 1e-2
#: Embedded sensor drawn as "the pulse in the uniform part" (far from striker and taper).
SENSOR_BEAD = 12
#: Beads of the uniform part whose sensors are used for timing (the striker transient is
#: over after ~3 beads; the protocol's fits use the same cut).
FIRST_CLEAN_BEAD = 4

# ------------------------------------------------------------------------------------------
# data helpers
# ------------------------------------------------------------------------------------------
def _eps_theory(settings) -> float:
    """The eps of the closed-form predictions: 1 for elastic runs, else the calibrated target."""
    return 1.0 if getattr(settings, "elastic", False) else float(getattr(settings, "eps", PAPER["eps"]))


def _wall_signal(study, n: int) -> tuple[np.ndarray, np.ndarray]:
    ds = study.wall[int(n)]
    return ds.time.values, ds.wall_force.values


def _sensor_signal(study, bead: int) -> tuple[np.ndarray, np.ndarray]:
    ds = study.wall[int(study.truncations[-1])]
    return ds.time.values, ds.sensor_force.sel(sensor=bead).values


def _n0(study) -> int:
    return int(study.truncations[0])


def _cut(t: np.ndarray, f: np.ndarray, centre: float, window: tuple[float, float]):
    sel = (t >= centre + window[0]) & (t <= centre + window[1])
    return t[sel], f[sel]


def _spectra(study):
    """Spectra of the wall pulse of the uniform chain (n0) and of the full chain (N)."""
    n_in, n_out = _n0(study), int(study.truncations[-1])
    cuts = []
    for n in (n_in, n_out):
        t, f = _wall_signal(study, n)
        fit = study.wall_fits[n]
        tc, fc = _cut(t, f - fit.baseline, fit.time_of_flight, SPECTRUM_WINDOW_S)
        cuts.append((tc, fc))
    nfft = 8 * max(c[0].size for c in cuts)
    spec = analysis.compare_spectra(cuts[0][0], cuts[0][1], cuts[1][0], cuts[1][1], nfft=nfft,
                                    window="hann", normalize="max")
    return spec, n_in, n_out


def _in_window(x_ms: np.ndarray, f: np.ndarray, window: tuple[float, float] = PULSE_WINDOW_MS, margin: float = 0.05):
    """The samples of a pulse inside the shown window [ms] (a little beyond): drawing the whole
    8 ms record in every panel cost most of the drawing time."""
    sel = (x_ms >= window[0] - margin) & (x_ms <= window[1] + margin)
    return x_ms[sel], f[sel]


def _spectrum_extent(freq: np.ndarray, power: np.ndarray, level: float) -> float:
    """Frequency [Hz] beyond which the max-normalised ``power`` stays below ``level``, rounded up
    to 1, 2 or 5 times a power of ten."""
    above = np.nonzero(power >= level * power.max())[0]
    f = float(freq[above[-1]]) if above.size else float(freq[-1])
    p = 10 ** math.floor(math.log10(f))
    return next(m * p for m in (1, 2, 5, 10) if m * p >= f)


def _bandwidth(freq: np.ndarray, power: np.ndarray, level: float = BANDWIDTH_LEVEL) -> float:
    """Highest frequency [Hz] where the max-normalised power is still >= ``level``."""
    above = np.nonzero(power >= level * power.max())[0]
    return float(freq[above[-1]]) if above.size else math.nan


def _uniform_speed(study, settings, beads: np.ndarray | list[int]) -> np.ndarray:
    """Wave speed v_n = v_1 eps^((n - 1)/5) of the uniform-part fit (eq. 8 with q = 0)."""
    return study.v1 * _eps_theory(settings) ** ((np.asarray(beads, float) - 1.0) / 5.0)


def _tof_prediction(study, settings, q: float) -> tuple[np.ndarray, np.ndarray]:
    """Ballistic time of flight T_n for n = 0..N (paper Sec. III).

    n <= n0: the uniform-part fit T_n = T0 + (phi0/v1)(1 - eps^(-n/5))/(1 - eps^(-1/5)); beyond,
    T_n = T_(n-1) + phi_n / v_n with the actual diameters and v_n from eq. 8 with tapering
    ``q`` (q = 0: restitution only, the paper's T(eps; q = 0)).
    """
    phi = study.chain.diameters
    n0 = _n0(study)
    eps = _eps_theory(settings)
    beads = np.arange(0, phi.size + 1)
    T = np.empty(beads.size)
    T[: n0 + 1] = theory.time_of_flight_uniform(beads[: n0 + 1], float(phi[0]), study.v1, study.T0, eps)
    v = float(_uniform_speed(study, settings, [n0])[0])
    ratio = float(theory.ballistic_ratios(q, eps).speed)
    for n in range(n0 + 1, phi.size + 1):
        v *= ratio
        T[n] = T[n - 1] + phi[n - 1] / v
    return beads, T


def _sensor_tof(study) -> tuple[np.ndarray, np.ndarray]:
    beads = np.asarray(study.sensor_beads)
    T = study.sensor_series("time_of_flight")
    use = (beads >= FIRST_CLEAN_BEAD) & np.isfinite(T)
    return beads[use], T[use]


def _wall_tof_shift(study) -> float:
    """Shift [s] that puts the wall time of flight at n0 on the embedded sensor's at n0."""
    n0 = _n0(study)
    t_sensor = study.sensor_fits[n0].time_of_flight
    return float(t_sensor - study.wall_fits[n0].time_of_flight)


def _anchored(pred: np.ndarray, beads: np.ndarray, n_anchor: int, value: float) -> np.ndarray:
    """Scale a per-bead prediction so that it equals ``value`` at bead ``n_anchor``."""
    k = int(np.nonzero(beads == n_anchor)[0][0])
    return pred * (value / pred[k])


def _prediction(study, settings, q: float | None):
    """theory.predict_chain for the study's chain (eq. 7 forces, eq. 8 speeds, tau_n)."""
    material = study.chain.materials[0]
    f0 = study.wall_fits[_n0(study)].peak_force
    return theory.predict_chain(study.chain.diameters, material, f0, _eps_theory(settings), _n0(study),
                                0.0, q)


# ------------------------------------------------------------------------------------------
# Figs. 1 and 2
# ------------------------------------------------------------------------------------------
def _fig_pulses(study, settings, chain_label: str, q_label: str) -> Figure:
    fig = paper_figure(7.0, 7.4)
    axes = fig.subplots(4, 2)
    flat = axes.ravel()
    n0 = _n0(study)
    letters = "abcdefgh"
    t_ms = lambda t, T: (t - T) * 1e3  # noqa: E731

    # (a) the pulse in the uniform chain: wall force of the n0-bead chain and embedded sensor
    ax = flat[0]
    t, f = _wall_signal(study, n0)
    fit = study.wall_fits[n0]
    ax.plot(*_in_window(t_ms(t, fit.time_of_flight), f), color=CK, label=f"wall (n = {n0})")
    ts, fs = _sensor_signal(study, SENSOR_BEAD)
    sfit = study.sensor_fits[SENSOR_BEAD]
    ax.plot(*_in_window(t_ms(ts, sfit.time_of_flight), fs), color=C1, ls="--", label=f"sensor, bead {SENSOR_BEAD}")
    ax.text(0.97, 0.95, f"$\\phi$ = {study.chain.diameters[0] * 1e3:.0f} mm\n"
            f"$F_m$ = {fit.peak_force:.2f} N\n$\\tau$ = {fit.duration * 1e6:.0f} $\\mu$s",
            transform=ax.transAxes, ha="right", va="top")
    ax.legend(loc="upper right", bbox_to_anchor=(1.0, 0.66))  # right of the pulse, under the numbers
    panel_tag(ax, "(a)")
    fmax = max(float(np.max(f)), float(np.max(fs)))

    # (b)-(g) wall force of the truncated chains
    shown = [n for n in FIG12_TRUNCATIONS if n in study.wall]
    for k, n in enumerate(shown):
        ax = flat[k + 1]
        t, f = _wall_signal(study, n)
        fit = study.wall_fits[n]
        ax.plot(*_in_window(t_ms(t, fit.time_of_flight), f), color=CK)
        xm = np.linspace(-math.pi / 2 * fit.duration, 0.0, 80)
        ax.plot(xm * 1e3, fit.model(xm + fit.time_of_flight), color=C2, ls="--", lw=0.9)
        ax.text(0.97, 0.95, f"n = {n}, $\\phi_{{{n}}}$ = {study.chain.diameters[n - 1] * 1e3:g} mm\n"
                f"$F_m$ = {fit.peak_force:.2f} N\n$\\tau$ = {fit.duration * 1e6:.0f} $\\mu$s",
                transform=ax.transAxes, ha="right", va="top")
        panel_tag(ax, f"({letters[k + 1]})")
        fmax = max(fmax, float(np.max(f)))
    for ax in flat[: len(shown) + 1]:
        ax.set_xlim(*PULSE_WINDOW_MS)
        ax.set_ylim(-0.04 * fmax, 1.12 * fmax)
        ax.set_ylabel("F [N]")
        ax.set_xlabel("t - T [ms]")
    if shown:
        flat[1].plot([], [], color=C2, ls="--", lw=0.9, label="$F_m\\cos^6[(t-T)/\\tau]$ fit")
        flat[1].legend(loc="center right", bbox_to_anchor=(1.0, 0.38))

    # (h) power spectra: incoming (uniform chain) and outgoing (full tapered chain)
    ax = flat[7]
    spec, n_in, n_out = _spectra(study)
    # Log frequency axis from 0.2 kHz to where the outgoing spectrum leaves the plot (1e-8): the
    # two centroids, ~20 % apart, stay distinguishable and no part of the axis is empty.
    f_hi = _spectrum_extent(spec.freq_out, spec.power_out, 1e-8)
    for freq, power, c, col, ls, lab in ((spec.freq_in, spec.power_in, spec.centroid_in, C1, "--",
                                          f"in: n = {n_in} (uniform)"),
                                         (spec.freq_out, spec.power_out, spec.centroid_out, C2, ":",
                                          f"out: n = {n_out}")):
        keep = (freq > 0) & (freq <= f_hi)
        ax.loglog(freq[keep] * 1e-3, power[keep], color=col, label=lab)
        ax.axvline(c * 1e-3, color=col, ls=ls, lw=0.9)
    ax.set_xlim(0.2, f_hi * 1e-3)
    ax.set_ylim(1e-8, 3)
    ax.set_xlabel("f [kHz]")
    ax.set_ylabel("power [arb. units]")
    bw_in, bw_out = _bandwidth(spec.freq_in, spec.power_in), _bandwidth(spec.freq_out, spec.power_out)
    # One box in the empty lower left (low frequencies, low power): the numbers, then the key.
    ax.legend(loc="lower left", title=f"centroids (vertical lines):\n{spec.centroid_in * 1e-3:.2f} $\\to$ "
              f"{spec.centroid_out * 1e-3:.2f} kHz\n-20 dB bandwidth:\n{bw_in * 1e-3:.1f} $\\to$ "
              f"{bw_out * 1e-3:.1f} kHz", title_fontsize=7, alignment="left")
    panel_tag(ax, "(h)", "upper right")
    desc = settings.describe() if hasattr(settings, "describe") else {}
    run = (f"; {desc.get('law', '?')} contacts, striker {desc.get('striker_diameter', math.nan) * 1e3:g} mm at "
           f"{desc.get('striker_velocity', math.nan):g} m/s") if desc else ""
    fig.suptitle(f"{chain_label}: q = {study.q * 100:.2f} % ({q_label}){run}\n"
                 f"(a)-(g): force against t - T, T = fitted time of flight of each pulse", fontsize=8)
    return fig


@styled
def fig1(study1, settings) -> Figure:
    """Paper Fig. 1: pulse evolution in chain 1 (q1 = 5.60 %).

    (a) the pulse in the uniform chain: wall force of the chain cut after bead n0 = 16 (solid)
    and the sensor embedded in bead 12 of the full chain (dashed), each against t - T with its
    own fitted time of flight T; (b)-(g) wall force of the chain truncated after beads 18, 20,
    22, 24, 26, 28 against t - T, with the cos^6 fit of the loading part (dotted); all force
    panels share one force scale so the decay is visible; (h) power spectra (arbitrary units,
    each normalised to its maximum) of the wall pulse of the uniform chain (in) and of the full
    chain (out), cut to T +- 0.6 ms with a Hann window, on log-log axes up to where the outgoing
    spectrum falls below 1e-8, with their spectral centroids (vertical lines).

    Parameters
    ----------
    study1:
        :class:`~hertzchain.paper.protocol.ChainStudy` of ``"chain1"``.
    settings:
        The run's :class:`~hertzchain.paper.protocol.Settings` (for the annotations).
    """
    return _fig_pulses(study1, settings, "Chain 1", "$q_1$")


@styled
def fig2(study2, settings) -> Figure:
    """Paper Fig. 2: the same as :func:`fig1` for chain 2 (q2 = 8.27 %, N = 28)."""
    return _fig_pulses(study2, settings, "Chain 2", "$q_2$")


# ------------------------------------------------------------------------------------------
# Fig. 3
# ------------------------------------------------------------------------------------------
@styled
def fig3(misalignment: dict, substitutions: dict, settings) -> Figure:
    """Paper Fig. 3: sensitivity to misalignment and to a local change of the tapering.

    (a) wall force at the end of the full chain 2 with bead 22 (phi = 16 mm) offset
    perpendicular to the axis by e (legend, in mm; e = fraction x phi_22); (b) the same for bead
    28 (phi = 9 mm), the bead touching the wall; (c) wall force of chain 1 cut after bead 24
    (reference) and with the dq/q = +1 and -1 single-bead substitutions. In each panel the time
    axis is t - T with T the time of flight of the panel's reference (aligned / unmodified)
    chain, so arrival-time shifts stay visible. The offsets change F by less than 0.1 % of F_m,
    so below each panel the difference from its reference chain, F - F(reference) [mN], is drawn
    on its own scale (a', b', c'), its key giving the changes of the cos^6 fits (F_m, tau, T).

    Parameters
    ----------
    misalignment:
        {(bead, fraction): dataset with ``wall_force``} from ``run_misalignment``.
    substitutions:
        {label: dataset} from ``run_substitutions`` (the unmodified chain labelled "reference").
    settings:
        The run's settings (unused beyond the title; kept for a uniform signature).
    """
    fig = paper_figure(3.4, 9.4)
    # Each panel: the forces, and below them the difference from the reference chain on its own
    # scale ((a), (b): the effect is < 0.1 % of F_m and the curves above coincide); the changes
    # of the cos^6 fits are the difference panel's key, so no text stands between the panels.
    grid = fig.add_gridspec(6, 1, height_ratios=[2.0, 1.15, 2.0, 1.15, 2.0, 1.15])
    axes = [fig.add_subplot(grid[i]) for i in range(6)]
    force_axes = [axes[0], axes[2], axes[4]]
    diff_axes = [axes[1], axes[3], axes[5]]
    beads = sorted({b for b, _ in misalignment})
    colours = [CK, C1, C2, C3, "#9467bd", "#8c564b"]
    styles = ["-", "--", "-.", ":", "-", "--"]
    panels = []
    for b in beads[:2]:
        fracs = sorted(fr for bb, fr in misalignment if bb == b)
        entries = []
        for fr in fracs:
            ds = misalignment[(b, fr)]
            phi = float(ds.diameter.sel(bead=b)) if "diameter" in ds else math.nan
            entries.append((f"e = {fr * phi * 1e3:.2f} mm ({fr * 100:.0f} %)", ds))
        phi_b = float(misalignment[(b, fracs[0])].diameter.sel(bead=b)) * 1e3
        panels.append((f"chain 2, bead {b} ($\\phi_{{{b}}}$ = {phi_b:g} mm) offset by e", entries,
                       ["aligned"] + [f"{fr * 100:.0f} %" for fr in fracs[1:]]))
    sub_entries = sorted(substitutions.items(), key=lambda e: e[0] != "reference")
    ref_phi = sub_entries[0][1].diameter.values
    labelled, short = [], []
    for lab, ds in sub_entries:
        changed = np.nonzero(ds.diameter.values != ref_phi)[0]
        if changed.size:  # name the substituted bead and its new diameter
            b = int(changed[0]) + 1
            lab = f"{lab} ($\\phi_{{{b}}}$ = {ds.diameter.values[b - 1] * 1e3:g} mm)"
        labelled.append((lab, ds))
        short.append(lab.split(" (")[0])
    panels.append((f"chain 1 cut after bead {ref_phi.size}: one bead substituted", labelled, short))

    for k, (ax, dax, (title, entries, short)) in enumerate(zip(force_axes, diff_axes, panels)):
        ref_ds = entries[0][1]
        ref_fit = analysis.fit_pulse(ref_ds.time.values, ref_ds.wall_force.values)
        t_ref = ref_fit.time_of_flight
        shown = lambda t: (t - t_ref >= PULSE_WINDOW_MS[0] * 1e-3) & (t - t_ref <= PULSE_WINDOW_MS[1] * 1e-3)  # noqa: E731
        fmax = 0.0
        for j, (lab, ds) in enumerate(entries):
            t, f = ds.time.values, ds.wall_force.values
            sel = shown(t)
            if j > 0:  # quote the changes of the cos^6 fit of each pulse in the difference panel's key
                fit = analysis.fit_pulse(t, f)
                delta = (f"$\\Delta F_m$ {100 * (fit.peak_force / ref_fit.peak_force - 1):+.2f} %, "
                         f"$\\Delta\\tau$ {100 * (fit.duration / ref_fit.duration - 1):+.2f} %, "
                         f"$\\Delta T$ {1e6 * (fit.time_of_flight - t_ref):+.1f} $\\mu$s")
                diff = (f - np.interp(t, ref_ds.time.values, ref_ds.wall_force.values)) * 1e3
                dax.plot((t[sel] - t_ref) * 1e3, diff[sel], color=colours[j % 6], ls=styles[j % 6],
                         label=f"{short[j]}: {delta}")
            ax.plot((t[sel] - t_ref) * 1e3, f[sel], color=colours[j % 6], ls=styles[j % 6], label=lab)
            fmax = max(fmax, float(np.max(f[sel])))
        ax.set_xlim(*PULSE_WINDOW_MS)
        ax.set_ylim(-0.04 * fmax, 1.12 * fmax)  # the data's range: the key sits above the tail
        ax.set_ylabel("F [N]")
        ax.set_title(title, pad=3, fontsize=7.5)
        ax.legend(loc="upper right", fontsize=6.5)
        panel_tag(ax, f"({'abc'[k]})")
        ax.tick_params(labelbottom=False)
        dax.sharex(ax)
        dax.axhline(0.0, color=CK, lw=0.6)
        dax.set_ylabel(f"F - F({short[0]})\n[mN]")
        dax.set_xlabel("t - T [ms]")
        lo, hi = dax.get_ylim()
        dax.set_ylim(lo, hi + 1.0 * (hi - lo))  # the upper half holds the key, the curves the lower
        dax.legend(loc="upper right", fontsize=5.5, handlelength=1.8, borderaxespad=0.2, borderpad=0.2,
                   labelspacing=0.2)
        panel_tag(dax, f"({'abc'[k]}')")
    return fig


# ------------------------------------------------------------------------------------------
# Fig. 4
# ------------------------------------------------------------------------------------------
def _collapse_records(study1, study2):
    """(label, bead, chain index, x, y) of every pulse of Figs. 1-2, rescaled by its fit
    (x = (t - T)/tau, y = (F - baseline)/F_m of the cos^6 fit)."""
    out = []
    for ci, study in enumerate((study1, study2)):
        n0 = _n0(study)
        for n in (n0,) + tuple(FIG12_TRUNCATIONS):
            if n not in study.wall or study.wall_fits.get(n) is None:
                continue
            t, f = _wall_signal(study, n)
            x, y = analysis.collapse(t, f, study.wall_fits[n])
            out.append((f"chain {ci + 1}, n = {n}", n, ci, x, y))
        if ci == 0:  # the embedded-sensor pulse of the uniform part (the same in both chains)
            t, f = _sensor_signal(study, SENSOR_BEAD)
            x, y = analysis.collapse(t, f, study.sensor_fits[SENSOR_BEAD])
            out.append((f"sensor, bead {SENSOR_BEAD}", SENSOR_BEAD, -1, x, y))
    return out


def _peak_normalised(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Divide a collapsed pulse by its maximum near (t - T)/tau = 0, so F_m is the pulse's peak.

    The cos^6 fit of the loading part gives T and tau; its amplitude is the peak of the wall
    pulses within ~0.5 %, but the embedded sensor reads the mean of two contacts a little
    apart in time, whose peak the loading fit misses by ~3 % (it showed as a curve peaking at 1.03).
    """
    near = np.abs(x) < 1.0
    return x, y / float(np.max(y[near]))


def _collapse_rms(records) -> float:
    """Largest rms deviation from cos^6 on the loading part -pi/2 < (t - T)/tau < 0."""
    worst = 0.0
    for *_, x, y in records:
        sel = (x > -math.pi / 2) & (x <= 0)
        worst = max(worst, float(np.sqrt(np.mean((y[sel] - np.cos(x[sel]) ** 6) ** 2))))
    return worst


@styled
def fig4(study1, study2) -> Figure:
    """Paper Fig. 4: self-similar collapse of the front pulse.

    Every pulse of Figs. 1-2 (wall force of both chains cut after beads 16, 18, ..., 28 and the
    embedded sensor of the uniform part) is plotted as (F - baseline)/F_m against (t - T)/tau,
    with T, tau (and the baseline) from its own cos^6 fit of the loading part and F_m its peak
    (the text quotes the rms deviation of the fits themselves). Colour: bead number n; solid:
    chain 1, dashed: chain 2, dotted: the sensor. The thick black curve is Nesterenko's cos^6
    over the loading part, the fitted range.
    """
    fig = paper_figure(3.4, 2.9)
    ax = fig.subplots()
    records = _collapse_records(study1, study2)
    cmap = matplotlib.colormaps["viridis"]
    beads = [r[1] for r in records]
    lo, hi = min(beads), max(beads)
    norm = matplotlib.colors.Normalize(lo, hi)
    for _lab, n, ci, x, y in records:
        x, y = _peak_normalised(x, y)
        sel = (x > -2.5) & (x < 3.5)
        ls = {0: "-", 1: "--", -1: ":"}[ci]
        ax.plot(x[sel], y[sel], color=cmap(norm(n)), ls=ls, lw=0.8)
    xs = np.linspace(-math.pi / 2, 0, 200)
    ax.plot(xs, np.cos(xs) ** 6, color="k", lw=2.2, alpha=0.55, label="$\\cos^6[(t-T)/\\tau]$")
    ax.plot([], [], color="0.4", ls="-", lw=0.8, label="chain 1 (wall)")
    ax.plot([], [], color="0.4", ls="--", lw=0.8, label="chain 2 (wall)")
    ax.plot([], [], color="0.4", ls=":", lw=0.8, label=f"sensor, bead {SENSOR_BEAD}")
    ax.set_xlim(-2.5, 3.5)
    ax.set_ylim(-0.08, 1.12)
    ax.set_xlabel("(t - T) / $\\tau$")
    ax.set_ylabel("F / $F_m$")
    ax.legend(loc="upper right")
    sm = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
    cb = fig.colorbar(sm, ax=ax, pad=0.01, fraction=0.05)
    cb.set_label("bead n")
    ax.text(0.03, 0.95, f"rms deviation of\nthe $\\cos^6$ fits\n(loading part)\n$\\leq$ {_collapse_rms(records):.3f}",
            transform=ax.transAxes, ha="left", va="top", fontsize=7)  # above the rise, left of the peak
    return fig


# ------------------------------------------------------------------------------------------
# Fig. 5
# ------------------------------------------------------------------------------------------
@styled
def fig5(study1, study2, settings) -> Figure:
    """Paper Fig. 5: characteristics of the pulse along both chains (left chain 1, right chain 2).

    (a) bead diameters phi_n and the fit phi_0 (1 - q)^(n - n0) for n > n0 with the chain's q;
    (b) peak wall force F_m against the truncation n, with eq. 7 for q = 0 (restitution only,
    dashed) and the chain's q (solid), anchored at the measured F_m at n0 = 16;
    (c) duration tau against n, with tau_n = (phi_n / 2) sqrt(10) / v_n, v_n from eq. 8 with
    q = 0 (dashed) and the chain's q (solid); eq. 5 gives the wave's speed but the wall pulse
    lasts ~1.09 times the inter-bead pulse, so each prediction is scaled to pass through the
    measured tau at n0 (only its shape along the chain is predicted);
    (d) front and tail momenta Q_F, Q_T of the wall pulse and their sum (momentum conservation).
    eps of the predictions: 1 for elastic runs, ``settings.eps`` otherwise.
    """
    fig = paper_figure(7.0, 7.0)
    axes = fig.subplots(4, 2, sharex="col")
    for col, study in enumerate((study1, study2)):
        n0 = _n0(study)
        phi = study.chain.diameters
        beads_all = np.arange(1, phi.size + 1)
        n = np.asarray(study.truncations)
        label = "12"[col]
        xlim = (n0 - 1.5, phi.size + 0.5)

        ax = axes[0, col]
        show = beads_all >= n0 - 1
        ax.plot(beads_all[show], phi[show] * 1e3, "o", color=CK, mfc="none", label="$\\phi_n$ (Table I)")
        nn = np.linspace(n0, phi.size, 100)
        ax.plot(nn, phi[0] * (1 - study.q) ** (nn - n0) * 1e3, color=C1,
                label=f"$\\phi_0(1-q)^{{n-n_0}}$, q = {study.q * 100:.2f} %")
        ax.set_ylabel("$\\phi_n$ [mm]")
        ax.legend(loc="upper right")
        ax.set_title(f"chain {label} ($q_{label}$)")
        panel_tag(ax, f"(a{label})", "lower left")

        ax = axes[1, col]
        F = study.series("peak_force")
        ax.plot(n, F, "o", color=CK, label="simulation (wall)")
        for q, ls, lab in ((0.0, "--", "eq. 7, q = 0"), (study.q, "-", f"eq. 7, q = {study.q * 100:.2f} %")):
            pred = _prediction(study, settings, q)
            yp = _anchored(pred.peak_force, pred.bead, n0, F[0])
            sel = pred.bead >= n0
            ax.plot(pred.bead[sel], yp[sel], color=C1 if q else C2, ls=ls, label=lab)
        lo, hi = ax.get_ylim()
        ax.set_ylim(lo, hi + 0.12 * (hi - lo))  # room for the panel tag above the q = 0 line
        ax.set_ylabel("$F_m$ [N]")
        ax.legend(loc="lower left")
        panel_tag(ax, f"(b{label})", "upper right")

        ax = axes[2, col]
        tau = study.series("duration")
        ax.plot(n, tau * 1e6, "o", color=CK, label="simulation (wall)")
        # tau_n = (phi_n/2) sqrt(10) / v_n with the chain's real phi_n in both curves: the dashed one
        # takes the speeds of q = 0 (restitution only), it is not a uniform chain, and says so
        for q, ls, lab in ((0.0, "--", "eq. 8, q = 0 (real $\\phi_n$)"),
                           (study.q, "-", f"eq. 8, q = {study.q * 100:.2f} %")):
            pred = _prediction(study, settings, q)
            yp = _anchored(pred.duration, pred.bead, n0, tau[0])
            sel = pred.bead >= n0
            ax.plot(pred.bead[sel], yp[sel] * 1e6, color=C1 if q else C2, ls=ls, label=lab)
        lo, hi = ax.get_ylim()
        ax.set_ylim(lo, hi + 0.08 * (hi - lo))
        ax.set_ylabel("$\\tau$ [$\\mu$s]")
        ax.legend(loc="upper right", title=f"anchored at n = {n0}", title_fontsize=7)
        panel_tag(ax, f"(c{label})", "lower left")

        ax = axes[3, col]
        QF, QT = study.series("front_momentum") * 1e3, study.series("tail_momentum") * 1e3
        ax.plot(n, QF, "o-", color=C1, label="$Q_F$ (front)")
        ax.plot(n, QT, "s-", color=C2, label="$Q_T$ (tail)")
        total = QF + QT
        spread = 100 * float(np.nanstd(total, ddof=1) / np.nanmean(total))
        ax.plot(n, total, "^-", color=CK, label=f"$Q_F + Q_T$ (rel. std {spread:.0f} %)")
        ax.set_ylabel("$Q_F$, $Q_T$ [mN s]")
        ax.set_xlabel("bead n")
        ax.set_ylim(0, 1.6 * float(np.nanmax(total)))
        ax.legend(loc="upper left", bbox_to_anchor=(0.0, 0.9), ncol=3, columnspacing=0.8, handlelength=1.4)
        panel_tag(ax, f"(d{label})", "upper right")
        for a in axes[:, col]:
            a.set_xlim(*xlim)
    return fig


# ------------------------------------------------------------------------------------------
# Fig. 6
# ------------------------------------------------------------------------------------------
@styled
def fig6(study1, study2, settings) -> Figure:
    """Paper Fig. 6: time of flight and speed along both chains (left chain 1, right chain 2).

    (a) time of flight T_n: embedded sensors for n <= n0 (open circles) and wall pulses of the
    truncated chains for n >= n0 (filled). The wall sensor sits behind the last bead, the
    embedded sensor inside bead n, so the wall series is shifted to meet the sensor at n0 (shift
    in the legend). Lines: the restitution-only prediction T(eps; q = 0) (dashed) - the fit
    T_n = T0 + (phi0/v1)(1 - eps^(-n/5))/(1 - eps^(-1/5)) of the uniform part, continued with
    T_n = T_(n-1) + phi_n / v_n and v_n = v1 eps^((n-1)/5) (eq. 8, q = 0) with the real
    diameters - and the ballistic prediction with the chain's q (solid, eq. 8);
    (b) T - T(eps; q = 0) for the data and the ballistic prediction with q;
    (c) local speed v_n = phi_n / (T_n - T_(n-1)), with the fit v_n = Q^(n - n') v_n' over the
    tapered part (solid, n' = n0 + 1) and the same law with the theoretical Q of eq. 8 (dashed).
    """
    fig = paper_figure(7.0, 6.2)
    axes = fig.subplots(3, 2, sharex="col")
    for col, study in enumerate((study1, study2)):
        label = "12"[col]
        n0 = _n0(study)
        phi = study.chain.diameters
        N = phi.size
        n_w = np.asarray(study.truncations)
        T_w = study.series("time_of_flight") + _wall_tof_shift(study)
        n_s, T_s = _sensor_tof(study)
        beads0, T_q0 = _tof_prediction(study, settings, 0.0)
        _, T_q = _tof_prediction(study, settings, study.q)
        shift_us = _wall_tof_shift(study) * 1e6

        ax = axes[0, col]
        ax.plot(n_s, T_s * 1e3, "o", color=CK, mfc="none", label="embedded sensors")
        ax.plot(n_w, T_w * 1e3, "o", color=CK, label=f"wall, shifted {shift_us:+.0f} $\\mu$s\n"
                f"(to meet the sensors at n = {n0})")
        # from bead 1: the fit's value at "bead 0" (the striker) is an extrapolation, slightly negative
        ax.plot(beads0[1:], T_q0[1:] * 1e3, color=C2, ls="--", label="T($\\epsilon$; q = 0)")
        ax.plot(beads0[n0:], T_q[n0:] * 1e3, color=C1, label=f"ballistic, q = {study.q * 100:.2f} %")
        ax.set_ylabel("T [ms]")
        lo, hi = ax.get_ylim()
        # A time of flight is never negative: the axis starts at the impact; the key sits in the
        # empty corner (early beads, long times), above the data.
        ax.set_ylim(0.0, 1.4 * hi)
        ax.legend(loc="upper left")
        ax.set_title(f"chain {label} ($q_{label}$)")
        panel_tag(ax, f"(a{label})", "lower right")

        ax = axes[1, col]
        ax.axhline(0, color=C2, ls="--", lw=0.8)
        ax.plot(n_s, (T_s - T_q0[n_s]) * 1e6, "o", color=CK, mfc="none", label="embedded sensors")
        ax.plot(n_w, (T_w - T_q0[n_w]) * 1e6, "o", color=CK, label="wall (shifted)")
        ax.plot(beads0[n0:], (T_q[n0:] - T_q0[n0:]) * 1e6, color=C1, label=f"ballistic, q = {study.q * 100:.2f} %")
        lo, hi = ax.get_ylim()
        ax.set_ylim(lo, hi + 0.1 * (hi - lo))  # room for the panel tag above the zero line
        ax.set_ylabel("T - T($\\epsilon$; q = 0) [$\\mu$s]")
        ax.legend(loc="lower left")
        panel_tag(ax, f"(b{label})", "upper right")

        ax = axes[2, col]
        vs = phi[0] / np.diff(T_s)
        ax.plot(n_s[1:], vs, "o", color=CK, mfc="none", label="embedded sensors")
        v_loc, b_loc = np.asarray(study.extras["v_local"]), np.asarray(study.extras["v_local_beads"])
        ax.plot(b_loc, v_loc, "o", color=CK, label="wall")
        n_ref = n0 + 1
        nn = np.linspace(n_ref, N, 60)
        v_ref = study.extras["v_ref"]
        ax.plot(nn, v_ref * study.Q_fit ** (nn - n_ref), color=C1,
                label=f"fit Q = {study.Q_fit:.3f} $\\pm$ {study.Q_fit_err:.3f}")
        ax.plot(nn, v_ref * study.Q_theory ** (nn - n_ref), color=C2, ls="--",
                label=f"eq. 8 $Q^{{th}}$ = {study.Q_theory:.3f}")
        pq = PAPER[study.name]
        ax.plot([], [], " ", label=f"paper: Q = {pq['Q_fit']:.3f} $\\pm$ {pq['Q_fit_err']:.3f}, "
                f"$Q^{{th}}$ = {pq['Q_theory']:.3f}")
        ax.set_ylabel("v [m/s]")
        ax.set_xlabel("bead n")
        ax.legend(loc="upper left")
        top = max(float(np.max(v_loc)), float(np.max(vs)))
        ax.set_ylim(0.9 * min(float(np.min(vs)), float(np.min(v_loc))), top * 1.22)
        panel_tag(ax, f"(c{label})", "lower right")
        for a in axes[:, col]:
            a.set_xlim(0, N + 1)
    return fig


# ------------------------------------------------------------------------------------------
# numbers for the report
# ------------------------------------------------------------------------------------------
def figure_summary(study1, study2, misalignment: dict | None = None,
                   substitutions: dict | None = None, settings=None) -> dict:
    """The numbers the figures show, as plain data for ``summary["figures"]`` of the report.

    Keys: ``spectra`` {chain: {n_in, n_out, centroid_in_hz, centroid_out_hz, bandwidth_in_hz,
    bandwidth_out_hz}} (Figs. 1h-2h; bandwidth at -20 dB), ``collapse_rms``
    (largest rms deviation from cos^6 on the loading part, Fig. 4) and ``collapse_pulses`` (how many
    pulses Fig. 4 draws), ``wall_tof_shift_s``
    {chain: shift of Fig. 6a}, ``tof_gain_s`` {chain: T(eps; q=0) - T at the last bead};
    with the Fig. 3 data also ``misalignment`` [{bead, offset_fraction, offset_m, peak_force,
    duration, time_of_flight}] (one entry per run) and ``substitutions`` {label: {peak_force, duration,
    time_of_flight}} (from the cos^6 fit of each wall pulse).
    """
    out: dict = {"spectra": {}, "wall_tof_shift_s": {}, "tof_gain_s": {}}
    for study in (study1, study2):
        spec, n_in, n_out = _spectra(study)
        out["spectra"][study.name] = {
            "n_in": n_in, "n_out": n_out, "centroid_in_hz": spec.centroid_in,
            "centroid_out_hz": spec.centroid_out,
            "bandwidth_in_hz": _bandwidth(spec.freq_in, spec.power_in),
            "bandwidth_out_hz": _bandwidth(spec.freq_out, spec.power_out)}
        out["wall_tof_shift_s"][study.name] = _wall_tof_shift(study)
        if settings is not None:
            _, T_q0 = _tof_prediction(study, settings, 0.0)
            T_last = study.series("time_of_flight")[-1] + _wall_tof_shift(study)
            out["tof_gain_s"][study.name] = float(T_q0[-1] - T_last)
    records = _collapse_records(study1, study2)
    out["collapse_rms"] = _collapse_rms(records)
    out["collapse_pulses"] = len(records)
    if misalignment:
        rows = []
        for (b, fr), ds in sorted(misalignment.items()):
            fit = analysis.fit_pulse(ds.time.values, ds.wall_force.values)
            rows.append({"bead": int(b), "offset_fraction": float(fr),
                         "offset_m": float(fr * ds.diameter.sel(bead=b)),
                         "peak_force": fit.peak_force, "duration": fit.duration,
                         "time_of_flight": fit.time_of_flight})
        out["misalignment"] = rows
    if substitutions:
        out["substitutions"] = {}
        for lab, ds in substitutions.items():
            fit = analysis.fit_pulse(ds.time.values, ds.wall_force.values)
            out["substitutions"][lab] = {"peak_force": fit.peak_force, "duration": fit.duration,
                                         "time_of_flight": fit.time_of_flight}
    return out
