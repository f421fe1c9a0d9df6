"""Where the model and the paper disagree: the reproduction under other model variants.

The reproduction's own run uses one contact law and holds misaligned beads rigidly on their
offset line. This module runs the same protocol under the variants that decide the paper's
unexplained observations and measures them:

- **contact laws** (paper Figs. 5b-c, eqs. 6-8): elastic, Kuwabara-Kono with one constant A
  (:class:`~hertzchain.contact.Viscoelastic`), with A following each contact's collision time
  (:class:`~hertzchain.contact.ScaledViscoelastic`, the same eps in every bead size, which is
  what eq. 6 assumes) and with A following its square
  (:class:`~hertzchain.contact.SizedViscoelastic`, a restitution falling with speed and a
  steel-like striker bounce), and the dashpot following each contact pair
  (:class:`~hertzchain.contact.ScaledDashpot`), each calibrated to the paper's eps on the 26 mm
  beads;
- **lateral freedom** (Fig. 3a-b): the misaligned beads of chain 2 free to move across the axis
  in a round groove (:class:`~hertzchain.runs.track.Track`), without and with Coulomb friction.

:func:`law_numbers` and :func:`misalignment_numbers` reduce the runs to the plain numbers stored
in ``summary.json`` (``fidelity``), from which :mod:`hertzchain.paper.claims` writes its verdicts
and :func:`fig_laws` / :func:`fig3_lateral` draw (``--from-data`` redraws them).
"""

from __future__ import annotations

import contextlib
import dataclasses
import multiprocessing
import time
import warnings
from typing import TYPE_CHECKING, Any, Callable

import numpy as np
from matplotlib.figure import Figure

from .. import analysis, theory
from ..parallel import usable_cores
from ..chain import paper_chain
from ..interrupts import forked_worker_init, start_forked
from ..errors import ConfigError, ElasticLimitWarning, HertzchainError
from ..model import Model, Wall

if TYPE_CHECKING:
    from multiprocessing.sharedctypes import SynchronizedArray
from ..probes import Probes
from ..runs.track import Track, simulate_lateral
from . import protocol
from .law_figure import LAW_STYLE, fig_laws  # noqa: F401 - drawn apart, re-exported here
from .values import PAPER
from ..laws import is_conservative

__all__ = ["LAW_VARIANTS", "RESTITUTION_SPEEDS", "TRACKS", "TAIL_WINDOW_S", "LawVariants", "law_numbers",
           "run_lateral_misalignment", "warm_lateral", "misalignment_numbers", "tail_oscillation", "fig_laws", "fig3_lateral",
           "count_variant_runs"]

#: Contact-law variants of the chain studies (the run's own law is one of them or is added).
LAW_VARIANTS = ("elastic", "viscoelastic", "viscoelastic_scaled", "viscoelastic_sized", "dashpot_scaled")

#: Impact speeds [m/s] of each variant's restitution trend (:func:`law_numbers`): the pulse's bead
#: speeds in the chain (~1e-2 m/s), the striker's 0.2 m/s, and two decades either side.
RESTITUTION_SPEEDS = (1e-4, 1e-2, 0.2, 1.0)

#: Lateral-freedom variants of Fig. 3a-b. The paper does not describe its track; a round groove
#: of 15 mm radius (just wider than the 26 mm beads) gives the 16 mm bead a gravity restoring
#: stiffness m g / (R_g - R) ~ 23 N/m, negligible during a ~0.1 ms pulse (the bead is
#: effectively free across the axis while the pulse passes); mu = 0.2 is a dry steel-on-steel
#: sliding coefficient.
TRACKS = {"lateral": Track(groove_radius=15e-3), "lateral_friction": Track(groove_radius=15e-3, friction=0.2)}

#: Window of t - T [s] where the paper sees the tail's oscillation (its peak near 0.38 ms).
TAIL_WINDOW_S = (0.25e-3, 0.55e-3)

N0 = PAPER["n0"]


def _variant_settings(settings: protocol.Settings, law: str) -> protocol.Settings:
    if is_conservative(law):
        return dataclasses.replace(settings, elastic=True)
    return dataclasses.replace(settings, elastic=False, law=law)


def _run_law(settings: protocol.Settings) -> str:
    return "elastic" if settings.elastic else settings.law


def count_variant_runs(settings: protocol.Settings) -> int:
    """Simulations :class:`LawVariants` and :func:`run_lateral_misalignment` make (progress bar)."""
    per_law = (PAPER["chain1"]["n_beads"] - N0 + 1) + (PAPER["chain2"]["n_beads"] - N0 + 1)
    others = sum(1 for law in LAW_VARIANTS if law != _run_law(settings))
    return others * per_law + len(TRACKS) * 4


def _variant_numbers(settings: protocol.Settings, law: str, progress: Callable[[str], None] | None = None) -> dict:
    """:func:`law_numbers` of one variant: the chain studies of both chains under ``law``, run here."""
    s = _variant_settings(settings, law)
    return law_numbers({law: {name: protocol.run_chain_study(name, s, progress) for name in ("chain1", "chain2")}},
                       settings)[law]


class LawVariants:
    """The chain studies of the other contact laws (:data:`LAW_VARIANTS`), shared with a process
    forked when this is made, so that they run on a second core beside the rest of the reproduction.

    The variants are claimed one at a time under a lock: the forked process takes them from the
    front of the list from the start, the caller from the back once it calls :meth:`finish`, so
    the two finish together whatever each one's other work (one core, or no ``fork``: the caller
    runs them all in :meth:`finish`, as before). Only the plain numbers of :func:`law_numbers`
    come back from the fork, never the traces; an error there is raised by :meth:`finish` as it
    would have been here (a :class:`~hertzchain.errors.ConfigError` naming its field). :meth:`cancel`
    stops the fork (after a failure).

    Parameters
    ----------
    settings : Settings
        The reproduction's settings; its own law is not among the variants run.
    """

    def __init__(self, settings: protocol.Settings) -> None:
        self.settings = settings
        self.laws = [law for law in LAW_VARIANTS if law != _run_law(settings)]
        self._proc = None
        if not self.laws or usable_cores() < 2 or "fork" not in multiprocessing.get_all_start_methods():
            self._ends: list[int] | SynchronizedArray = [0, len(self.laws)]
            self._lock = None
            return
        ctx = multiprocessing.get_context("fork")
        ends = ctx.Array("i", [0, len(self.laws)])
        self._ends, self._lock = ends, ends.get_lock()
        self._reader, writer = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(target=self._forked, args=(writer,), daemon=True)
        start_forked(self._proc)
        writer.close()

    def _claim(self, front: bool) -> str | None:
        """The next variant of the list's front (the fork) or back (the caller); None when none is left."""
        with self._lock or contextlib.nullcontext():
            lo, hi = self._ends[0], self._ends[1]
            if lo >= hi:
                return None
            self._ends[0 if front else 1] = lo + 1 if front else hi - 1
            return self.laws[lo if front else hi - 1]

    def _forked(self, writer) -> None:
        forked_worker_init()
        try:
            out = {}
            while (law := self._claim(front=True)) is not None:
                out[law] = _variant_numbers(self.settings, law)
            writer.send(("ok", out))
        except ConfigError as exc:  # an input no variant can run (an eps a law cannot reach): the caller's own
            writer.send(("config", (exc.field, exc.message)))
        except HertzchainError as exc:  # a user's error of one message: it pickles as it is
            writer.send(("hertzchain", exc))
        except Exception as exc:  # noqa: BLE001 - reported by the caller, which names it
            writer.send(("error", f"{type(exc).__name__}: {exc}"))
        finally:
            writer.close()

    def finish(self, studies: dict, progress: Callable[[str], None] | None = None) -> dict:
        """:func:`law_numbers` of the run's own studies and of every variant, the run's own law first.

        Parameters
        ----------
        studies : dict
            {"chain1": ChainStudy, "chain2": ChainStudy} of the run's own law (not rerun).
        progress : callable, optional
            Called with a message after each simulation (the fork's, when its numbers arrive).

        Returns
        -------
        dict
            {law: numbers}, as :func:`law_numbers`.
        """
        own = _run_law(self.settings)
        out = law_numbers({own: studies}, self.settings)
        while (law := self._claim(front=False)) is not None:
            out[law] = _variant_numbers(self.settings, law, progress)
        if self._proc is not None:
            try:
                status, theirs = self._reader.recv()
            except EOFError:
                status, theirs = "error", f"the process running them ended with exit code {self._proc.exitcode}"
            finally:
                self.cancel()
            if status == "config":
                raise ConfigError(*theirs)
            if status == "hertzchain":
                raise theirs
            if status != "ok":
                raise RuntimeError(f"the contact-law variants' runs failed: {theirs}")
            out.update(theirs)
            per_law = (PAPER["chain1"]["n_beads"] - N0 + 1) + (PAPER["chain2"]["n_beads"] - N0 + 1)
            for law in theirs:
                for _ in range(per_law):
                    if progress:
                        progress(f"contact-law variant {law}")
        return {law: out[law] for law in [own, *(v for v in LAW_VARIANTS if v != own)]}

    def cancel(self) -> None:
        """Stop the forked process (nothing else to undo: it writes no file)."""
        if self._proc is not None:
            if self._proc.is_alive():
                self._proc.terminate()
            self._proc.join()
            self._reader.close()
            self._proc = None


def _reflection(study, bead: int = 12) -> float:
    """Largest force at the sensor in ``bead`` after its pulse has passed, over that pulse's F_m.

    Window: from T_b + 3 tau_b (the pulse is over) until T_w + (T_w - T_b) / 2, T_w the wall
    pulse's time of flight: a wave reflected by the taper would cross the sensor there, the
    wall's echo cannot yet (it needs ~T_w - T_b to come back).
    """
    n = int(study.truncations[-1])
    ds = study.wall[n]
    fit, wall = study.sensor_fits.get(bead), study.wall_fits.get(n)
    if fit is None or wall is None or "sensor_force" not in ds:
        return float("nan")
    t, f = ds.time.values, ds.sensor_force.sel(sensor=bead).values
    sel = (t > fit.time_of_flight + 3 * fit.duration) & (t < wall.time_of_flight + 0.5 * (wall.time_of_flight - fit.time_of_flight))
    return float(f[sel].max() / fit.peak_force) if sel.any() else float("nan")


def _chain_numbers(study, eps: float) -> dict:
    """F_m and tau along the chain, their ratios N/n0 and the eq. 7-8 predictions (paper Sec. III)."""
    F, tau = study.series("peak_force"), study.series("duration")
    beads = np.asarray(study.truncations)
    n0, N = int(beads[0]), int(beads[-1])
    phi = study.chain.diameters
    r, r0 = theory.ballistic_ratios(study.q, eps), theory.ballistic_ratios(0.0, eps)
    qf, qt = study.series("front_momentum"), study.series("tail_momentum")
    total = qf + qt
    return {
        "beads": beads.tolist(), "peak_force": F.tolist(), "duration": tau.tolist(),
        "peak_force_ratio": float(F[-1] / F[0]), "duration_ratio": float(tau[-1] / tau[0]),
        # eq. 7: F_m ratio per bead (1 - q)^2 eps^(6/5)...; tau_n = (phi_n/2) sqrt(10) / v_n, v_n from eq. 8
        "eq7_peak_force_ratio": r.force ** (N - n0), "eq7_peak_force_ratio_q0": r0.force ** (N - n0),
        "eq8_duration_ratio": float(phi[N - 1] / phi[n0 - 1]) / r.speed ** (N - n0),
        "eq8_duration_ratio_q0": float(phi[N - 1] / phi[n0 - 1]) / r0.speed ** (N - n0),
        "Q_fit": study.Q_fit, "Q_fit_err": study.Q_fit_err, "Q_theory": study.Q_theory,
        "eps_measured": study.eps_measured,
        "tail_to_front": float(qt[-1] / qf[-1]),
        "tail_to_front_at": {str(int(n)): float(b / a) for n, a, b in zip(beads, qf, qt)},
        "momentum_spread": float(np.std(total, ddof=1) / np.mean(total)),
        "reflection_at_sensor": _reflection(study),
    }


def law_numbers(variants: dict[str, dict], settings: protocol.Settings) -> dict:
    """Plain numbers of every law variant: {law: {"chain1": {...}, "chain2": {...}, "figures": {...}}}.

    Per chain: F_m and tau along the chain and their ratios F_m(N)/F_m(16), tau(N)/tau(16)
    beside eq. 7 (forces) and eq. 8 (durations) with the chain's q and with q = 0, eps of the
    variant (1 elastic, else the calibrated target); Q_fit, eps measured back, the tail's share
    Q_T/Q_F, the spread of Q_F + Q_T, the force left at the sensor in bead 12 after the pulse
    (a reflected wave would show there); ``figures`` holds the spectral centroids, the time-of-flight
    gain and the Fig. 4 collapse of :func:`hertzchain.paper.figures.figure_summary`;
    ``striker_restitution`` the two-body restitution of the striker hitting a free first bead at
    the run's speed under the variant's calibrated law (:func:`hertzchain.restitution`), and
    ``restitution_trend`` that restitution at each speed of :data:`RESTITUTION_SPEEDS` [m/s]
    ({"speeds", "restitution"}: falling with speed as viscoelastic spheres' does, or rising).
    """
    from ..collision import restitution
    from .figures import figure_summary

    out = {}
    for law, studies in variants.items():
        s = _variant_settings(settings, law)
        eps = 1.0 if s.elastic else s.eps
        row: dict[str, Any] = {name: _chain_numbers(study, eps) for name, study in studies.items()}
        fs = figure_summary(studies["chain1"], studies["chain2"], None, None, s)
        row["figures"] = {"spectra": fs["spectra"], "tof_gain_s": fs["tof_gain_s"], "collapse_rms": fs["collapse_rms"]}
        the_law = studies["chain1"].law
        row["law"] = {"law": law, **{k: getattr(the_law, k) for k in ("A", "gamma") if hasattr(the_law, k)}}
        chain = studies["chain1"].chain
        bounce = [restitution(v, the_law, s.striker_diameter, s.material, float(chain.diameters[0]), chain.materials[0])
                  for v in (s.striker_velocity, *RESTITUTION_SPEEDS)]
        row["striker_restitution"] = bounce[0]
        row["restitution_trend"] = {"speeds": list(RESTITUTION_SPEEDS), "restitution": bounce[1:]}
        out[law] = row
    return out


#: Offsets (fractions of the bead's diameter) of the lateral-freedom variant of Fig. 3a-b.
LATERAL_FRACTIONS = (0.05, 0.10)


def warm_lateral(settings: protocol.Settings, law) -> None:
    """A short two-dimensional run of three beads of chain 2, the second offset, under ``law``: it
    compiles (or loads from Numba's cache) every kernel of :func:`run_lateral_misalignment`'s runs."""
    full = paper_chain("chain2", settings.material)
    warm = Model(full.truncated(3).with_offsets({2: 1e-3}), settings.striker(), Wall("none"), law)
    simulate_lateral(warm, TRACKS["lateral"], 1e-5, Probes(1e-6))  # free end: no wall pulse to wait for


def run_lateral_misalignment(settings: protocol.Settings, beads=protocol.MISALIGNED_BEADS,
                             fractions=LATERAL_FRACTIONS,
                             progress: Callable[[str], None] | None = None) -> tuple[dict, dict]:
    """Fig. 3a-b with lateral freedom: chain 2, bead ``b`` offset by ``fraction`` phi_b, on each track of :data:`TRACKS`.

    The aligned chain is not rerun: with every offset zero the 2D path gives the 1D run bit for
    bit (tests/test_lateral.py), so the rigid run's aligned record is the reference of every
    variant.

    Returns
    -------
    (dict, dict)
        {(track, bead, fraction): dataset} and the cost of the 2D runs: {"seconds", "bead_steps",
        "ns_per_bead_step"} (wall time over steps x bodies, compilation excluded by a warm-up run).
    """
    full = paper_chain("chain2", settings.material)
    law = protocol.contact_law(settings, full)
    out: dict = {}
    probes = Probes(settings.sample_interval, contacts=(full.n_beads,))
    warm_lateral(settings, law)  # so that the cost below is the run's, not the compiler's
    seconds, bead_steps = 0.0, 0
    for label, track in TRACKS.items():
        for b in beads:
            for frac in fractions:
                model = Model(full.with_offsets({b: frac * full.diameters[b - 1]}), settings.striker(),
                              Wall("flat"), law)
                t0 = time.perf_counter()
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", ElasticLimitWarning)
                    ds = simulate_lateral(model, track, settings.duration, probes)
                seconds += time.perf_counter() - t0
                bead_steps += int(ds.attrs["n_steps"]) * (full.n_beads + 1)
                out[(label, b, frac)] = ds
                if progress:
                    progress(f"Fig. 3a-b with lateral freedom ({label})")
    return out, {"seconds": seconds, "bead_steps": bead_steps, "ns_per_bead_step": 1e9 * seconds / max(bead_steps, 1)}


def tail_oscillation(time_s: np.ndarray, force: np.ndarray, fit) -> float:
    """Prominence [N] of the tail's largest oscillation peak within :data:`TAIL_WINDOW_S` of t - T.

    The paper sees the tail's oscillation (a peak near t - T = 0.38 ms, Fig. 3a-b) damped by a
    misaligned bead; the prominence (height above the higher of the two neighbouring minima) of
    the largest peak in the window measures it; 0 when the tail has no peak there.
    """
    from scipy.signal import find_peaks

    x = time_s - fit.time_of_flight
    sel = (x >= TAIL_WINDOW_S[0]) & (x <= TAIL_WINDOW_S[1])
    _, props = find_peaks(force[sel], prominence=0.0)
    return float(props["prominences"].max()) if props["prominences"].size else 0.0


def _fig3_row(ds, ref_fit, fit=None) -> dict:
    """The row of one Fig. 3 trace against the aligned chain's fit ``ref_fit`` (``fit``: the
    trace's own, when already made)."""
    t, f = ds.time.values, ds.wall_force.values
    fit = fit if fit is not None else analysis.fit_pulse(t, f)
    row = {"peak_force": fit.peak_force, "duration": fit.duration, "time_of_flight": fit.time_of_flight,
           "tail_oscillation": tail_oscillation(t, f, fit),
           "peak_force_change": fit.peak_force / ref_fit.peak_force - 1,
           "time_of_flight_change_s": fit.time_of_flight - ref_fit.time_of_flight}
    if "lateral_kinetic_energy" in ds:
        row["max_lateral_kinetic_energy"] = float(ds.lateral_kinetic_energy.max())
        row["friction_loss"] = float(ds.friction_loss[-1])
        row["striker_energy"] = float(ds.kinetic_energy[0])
    return row


def misalignment_numbers(rigid: dict, lateral: dict) -> dict:
    """Fig. 3a-b under each variant: {variant: {"bead:fraction": row}} with F_m, tau, T, the tail
    oscillation (:func:`tail_oscillation`) and their changes against the aligned chain; lateral
    rows also hold the largest transverse kinetic energy and the friction loss [J].

    Parameters
    ----------
    rigid : dict
        {(bead, fraction): dataset} of ``protocol.run_misalignment`` (fraction 0 = aligned).
    lateral : dict
        {(track, bead, fraction): dataset} of :func:`run_lateral_misalignment`.
    """
    # each trace is fitted once (the aligned chains' rows recur in every variant: a pulse fit of
    # an 80,000-sample trace is ~40 ms, on the reproduction's path to its figures)
    refs = {}
    for (b, fr), ds in sorted(rigid.items()):
        if fr == 0:
            fit = analysis.fit_pulse(ds.time.values, ds.wall_force.values)
            refs[b] = (fit, _fig3_row(ds, fit, fit))
    out: dict = {"rigid": {f"{b}:{fr:g}": dict(refs[b][1]) if fr == 0 else _fig3_row(ds, refs[b][0])
                           for (b, fr), ds in sorted(rigid.items())}}
    for (label, b, fr), ds in sorted(lateral.items()):
        rows = out.setdefault(label, {})
        rows[f"{b}:0"] = dict(refs[b][1])
        rows[f"{b}:{fr:g}"] = _fig3_row(ds, refs[b][0])
    return out


# ------------------------------------------------------------------------------------------
# figures
# ------------------------------------------------------------------------------------------
def fig3_lateral(rigid: dict, lateral: dict) -> Figure:
    """Paper Fig. 3a-b with the offset bead held on its line (rigid) and free across the axis.

    Rows: bead 22 and bead 28 of chain 2 offset by e = 5 % and 10 % of its diameter; columns: the
    1D model (rigid offset), the groove without friction and with friction (:data:`TRACKS`).
    Wall force against t - T, T the aligned chain's time of flight; the tail window of
    :func:`tail_oscillation` is shaded.

    Parameters
    ----------
    rigid : dict
        {(bead, fraction): dataset} (fraction 0 = aligned).
    lateral : dict
        {(track, bead, fraction): dataset}.

    Returns
    -------
    matplotlib.figure.Figure
        One row per bead, one column per variant.
    """
    from ..viz.style import STYLE, panel_tag, paper_figure
    from .figures import PULSE_WINDOW_MS

    import matplotlib

    beads = sorted({b for b, _ in rigid})
    variants = ["rigid", *TRACKS]
    titles = {"rigid": "rigid offset (1D)", "lateral": "free in a groove", "lateral_friction": "groove + friction 0.2"}
    with matplotlib.rc_context(STYLE):
        fig = paper_figure(7.0, 2.2 * len(beads))
        axes = np.atleast_2d(fig.subplots(len(beads), len(variants), sharey="row"))
        for i, b in enumerate(beads):
            ref = rigid[(b, 0.0)]
            ref_fit = analysis.fit_pulse(ref.time.values, ref.wall_force.values)
            fracs = sorted(fr for bb, fr in rigid if bb == b)
            for j, var in enumerate(variants):
                ax = axes[i, j]
                for fr, colour, ls in zip(fracs, ("0.2", "#1f77b4", "#d62728"), ("-", "--", "-.")):
                    ds = ref if fr == 0 else (rigid[(b, fr)] if var == "rigid" else lateral.get((var, b, fr)))
                    if ds is None:
                        continue
                    x = (ds.time.values - ref_fit.time_of_flight) * 1e3
                    ax.plot(x, ds.wall_force.values, color=colour, ls=ls, label=f"e = {100 * fr:.0f} %")
                ax.axvspan(TAIL_WINDOW_S[0] * 1e3, TAIL_WINDOW_S[1] * 1e3, color="0.9", zorder=0)
                ax.set_xlim(*PULSE_WINDOW_MS)
                ax.set_title(f"bead {b}: {titles.get(var, var)}", pad=3)
                ax.set_xlabel("t - T [ms]")
                panel_tag(ax, f"({chr(ord('a') + i * len(variants) + j)})")  # before the pulse: empty
            axes[i, 0].set_ylabel("wall force [N]")
            axes[i, 0].legend(loc="upper right")
    return fig
