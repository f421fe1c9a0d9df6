"""Shared helpers of the benchmark scripts (not part of the hertzchain package).

- :func:`machine_info`: what the numbers were measured on (saved in every JSON file);
- :func:`best_of`: wall-clock timing, best of N (the machine is shared: the minimum is the least
  disturbed run, the spread is reported too);
- the models every script uses (the contract chain, uniform chains, the paper's chain 1);
- :func:`solve_scipy`: ``scipy.integrate.solve_ivp`` on a chain, with either a plain vectorised
  NumPy right-hand side (:func:`numpy_rhs`, what a competent user writes) or hertzchain's compiled
  one (:func:`hertzchain.integrate.drivers.reference.make_rhs`), and the peak wall force refined on the
  dense output exactly as :mod:`hertzchain.integrate.drivers.reference` does.

Units are SI throughout (s, m, N), as in the package.
"""

from __future__ import annotations

import datetime as dt
import json
import math
import os
import platform
import subprocess
import time
import warnings
from pathlib import Path
from typing import Callable

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
REPO = HERE.parent

#: The contract chain of the core-engine issue: 16 x 26 mm, then 24, 23, 22 mm (AISI 52100).
CONTRACT_DIAMETERS_MM = [26.0] * 16 + [24.0, 23.0, 22.0]
#: Striker of the paper (Sec. II): 8 mm AISI 52100 ball. 0.5 m/s is the issue's contract speed.
STRIKER_DIAMETER = 8e-3
STRIKER_VELOCITY = 0.5
#: Bead diameter of the uniform benchmark chains [m] (the paper's monodisperse beads).
UNIFORM_DIAMETER = 26e-3


# ----------------------------------------------------------------------------- machine and timing
def cpu_model() -> str:
    """CPU model name from /proc/cpuinfo (Linux), else platform.processor()."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _git_commit() -> str | None:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True, timeout=10)
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "src"], cwd=REPO, capture_output=True,
                               text=True, timeout=10).stdout.strip()
        return out.stdout.strip() + (" (src/ has uncommitted changes)" if dirty else "") if out.returncode == 0 else None
    except (OSError, subprocess.SubprocessError):
        return None


def machine_info() -> dict:
    """CPU, core counts, library versions, date: saved with every result."""
    import numba
    import scipy

    import hertzchain

    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    try:
        load = list(os.getloadavg())
    except OSError:
        load = None
    return {
        "cpu_model": cpu_model(),
        "cpu_count": os.cpu_count(),
        "usable_cores": usable,
        "machine": platform.machine(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "numba_num_threads": numba.config.NUMBA_NUM_THREADS,
        "hertzchain": hertzchain.__version__,
        "hertzchain_commit": _git_commit(),
        "load_average_at_start": load,
        "date_utc": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
        "note": "shared machine: absolute times are noisy; ratios measured in the same run hold better",
    }


def best_of(fn: Callable[[], object], repeat: int) -> tuple[float, list[float], object]:
    """Run ``fn`` ``repeat`` times; return (best time [s], all times [s], last return value)."""
    times = []
    out = None
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), times, out


def steps_for(rate: float, n_beads: int, min_time: float, stride: int) -> int:
    """Steps (a multiple of ``stride``) for a run of ~1.6 x ``min_time`` [s] at ``rate`` bead-steps/s."""
    steps = 1.6 * min_time * rate / n_beads
    return int(max(1, math.ceil(steps / stride))) * stride


def calibrate(run: Callable[[int], object], n_beads: int, stride: int, min_time: float) -> int:
    """Steps for one measured call ``run(steps)`` whose stepping alone lasts ~1.6 x ``min_time``.

    A call costs ``fixed + steps x per_step``; the fixed part (packing, allocation, building the
    models of a batch) can dwarf a short trial, so the per-step cost is taken from the difference
    of two trial calls (``s`` and ``4 s`` steps), grown until their difference is >= min_time / 4.
    The JIT must be warm.
    """
    s = steps_for(2e8, n_beads, 0.005, stride)
    while True:
        t1, _, _ = best_of(lambda: run(s), 1)
        t4, _, _ = best_of(lambda: run(4 * s), 1)
        if t4 - t1 >= min_time / 4:
            break
        s *= 4
    per_step = (t4 - t1) / (3 * s)
    return int(math.ceil(1.6 * min_time / per_step / stride)) * stride


def measure(run: Callable[[int], object], steps: int, stride: int, repeat: int, min_time: float):
    """Best of ``repeat`` calls ``run(steps)``, lengthened until the best call lasts >= ``min_time``.

    Returns (steps, best time [s], all times [s] of the final round, last return value).
    """
    while True:
        best, times, out = best_of(lambda: run(steps), repeat)
        if best >= min_time:
            return steps, best, times, out
        steps = int(math.ceil(steps * 1.25 * min_time / best / stride)) * stride


def save_json(data: dict, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2, default=_jsonable) + "\n")


def _jsonable(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, Path):
        return str(x)
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


def table(rows: list[tuple], header: tuple) -> str:
    """Plain-text table (right-aligned columns after the first)."""
    cells = [tuple(str(c) for c in header)] + [tuple(str(c) for c in r) for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    lines = []
    for k, r in enumerate(cells):
        lines.append("  ".join(c.ljust(widths[i]) if i == 0 else c.rjust(widths[i]) for i, c in enumerate(r)))
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def fmt(x: float, digits: int = 3) -> str:
    return f"{x:.{digits}g}" if isinstance(x, (int, float)) and x == x else str(x)


# ----------------------------------------------------------------------------- models
def contract_model():
    """16 x 26 mm + 24, 23, 22 mm, AISI 52100, striker 8 mm at 0.5 m/s, flat wall."""
    import hertzchain as hc

    chain = hc.Chain.from_diameters(np.array(CONTRACT_DIAMETERS_MM) * 1e-3)
    return hc.Model(chain, hc.Striker(STRIKER_DIAMETER, STRIKER_VELOCITY), hc.Wall("flat"))


def uniform_model(n_beads: int):
    """``n_beads`` beads of 26 mm AISI 52100, striker 8 mm at 0.5 m/s, flat wall."""
    import hertzchain as hc

    return hc.Model(hc.Chain.uniform(n_beads, UNIFORM_DIAMETER), hc.Striker(STRIKER_DIAMETER, STRIKER_VELOCITY),
                    hc.Wall("flat"))


def paper_chain1_model():
    """The paper's Table I chain 1, striker 8 mm at 0.5 m/s, flat wall of the bead material."""
    import hertzchain as hc

    return hc.Model(hc.paper_chain("chain1"), hc.Striker(STRIKER_DIAMETER, STRIKER_VELOCITY), hc.Wall("flat"))


def quiet():
    """Silence the elastic-limit warning: the 0.5 m/s contract impact passes F_Y at the striker."""
    warnings.filterwarnings("ignore", message=".*elastic limit.*")
    try:
        from hertzchain.errors import ElasticLimitWarning

        warnings.simplefilter("ignore", ElasticLimitWarning)
    except ImportError:  # pragma: no cover
        pass


# ----------------------------------------------------------------------------- scipy baselines
def _viscous(system) -> tuple[str | None, np.ndarray]:
    """The system's viscous term: (None | "dashpot" | "kuwabara_kono", per-contact gamma or A)."""
    from hertzchain.laws import law_of_code

    spec = law_of_code(system.law)
    if not spec.dissipative:
        return None, np.zeros_like(system.kappa)
    if spec.plastic or spec.generated or system.law not in (1, 2):
        raise ValueError(f"the NumPy right-hand side writes the elastic, Kuwabara-Kono and dashpot laws, not {spec.name}")
    return ("kuwabara_kono" if system.law == 1 else "dashpot"), np.array(system.damping, dtype=float)


def numpy_rhs(system) -> Callable[[float, np.ndarray], np.ndarray]:
    """The right-hand side a competent user writes in plain vectorised NumPy (paper eq. 1).

    State y = [u_0..u_N, v_0..v_N] (striker and beads); the immovable wall sits at u = 0 after
    bead N, so the overlaps are delta_j = u_j - u_{j+1} with u_{N+1} = 0 (a free end has kappa_N = 0).
    Dissipative laws (the same as the model's): F = kappa delta^(3/2) + gamma r (dashpot) or
    kappa (delta^(3/2) + A delta^(1/2) r) (Kuwabara-Kono), r = d(delta)/dt, never attractive.
    """
    nb = system.n_beads + 1
    kappa = np.array(system.kappa, dtype=float)        # (N+1,) N/m^1.5, contact N = wall
    inv_m = 1.0 / np.array(system.mass[:nb], dtype=float)  # (N+1,) 1/kg
    zero = np.zeros(1)
    viscous, c = _viscous(system)

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        u = y[:nb]
        v = y[nb:]
        if viscous is None:
            delta = np.maximum(-np.diff(u, append=0.0), 0.0)   # u_j - u_{j+1}, never attractive
            f = kappa * delta**1.5                             # Hertz, F = kappa delta^(3/2)
        else:
            d = -np.diff(u, append=0.0)
            rate = -np.diff(v, append=0.0)
            delta = np.maximum(d, 0.0)
            f = kappa * delta**1.5 + (c * rate if viscous == "dashpot" else kappa * c * np.sqrt(delta) * rate)
            f = np.where(d >= 0.0, np.maximum(f, 0.0), 0.0)
        a = (np.concatenate((zero, f[:-1])) - f) * inv_m   # (F_{i-1} - F_i) / m_i
        return np.concatenate((v, a))

    return rhs


def wall_force(system, u_last, v_last):
    """The wall contact's force [N] at the last bead's displacement and velocity (arrays)."""
    kw = float(system.kappa[-1])
    viscous, c = _viscous(system)
    d = np.asarray(u_last, dtype=float)
    delta = np.maximum(d, 0.0)
    if viscous is None:
        return kw * delta**1.5
    cw = float(c[-1])
    v = np.asarray(v_last, dtype=float)
    f = kw * delta**1.5 + (cw * v if viscous == "dashpot" else kw * cw * np.sqrt(delta) * v)
    return np.where(d >= 0.0, np.maximum(f, 0.0), 0.0)


def solve_scipy(system, duration: float, method: str, rtol: float, rhs_kind: str = "numpy",
                sample_interval: float = 1e-7) -> dict:
    """Integrate with ``solve_ivp`` and return the peak wall force [N], its time [s] and counts.

    ``atol`` is ``rtol`` times the natural scale of each component (the striker contact's maximum
    overlap for positions, the striker speed for velocities), as in
    :func:`hertzchain.integrate.drivers.reference.run_reference`, so that a tolerance means the same thing
    for both right-hand sides. The state is sampled every ``sample_interval`` (the oscilloscope's
    100 ns, like hertzchain's probes); the wall-force maximum of the samples is refined on the
    dense output with ``minimize_scalar`` over the two neighbouring sample intervals.
    """
    from scipy.integrate import solve_ivp
    from scipy.optimize import minimize_scalar

    nb = system.n_beads + 1
    energy = 0.5 * system.mass[0] * system.v0[0] ** 2
    d_scale = (2.5 * energy / system.kappa[0]) ** 0.4
    v_scale = float(abs(system.v0).max())
    n_samples = int(np.floor(duration / sample_interval + 1e-9)) + 1
    t_eval = np.arange(n_samples) * sample_interval
    atol = [np.full(nb, rtol * d_scale), np.full(nb, rtol * v_scale)]
    y0 = [system.u0[:nb], system.v0[:nb]]
    if rhs_kind == "numpy":
        rhs = numpy_rhs(system)
    elif rhs_kind == "compiled":
        from hertzchain.integrate.drivers.reference import make_rhs

        rhs = make_rhs(system)  # state has one extra component: the dissipated energy
        atol.append([rtol * energy])
        y0.append([0.0])
    else:
        raise ValueError(rhs_kind)
    sol = solve_ivp(rhs, (0.0, t_eval[-1]), np.concatenate(y0), method=method, rtol=rtol,
                    atol=np.concatenate(atol), t_eval=t_eval, dense_output=True)
    if not sol.success:
        raise RuntimeError(f"solve_ivp({method}, rtol={rtol:g}) failed: {sol.message}")
    fw = wall_force(system, sol.y[nb - 1], sol.y[2 * nb - 1])   # wall force at the samples
    k = int(np.argmax(fw))
    lo, hi = t_eval[max(k - 1, 0)], t_eval[min(k + 1, n_samples - 1)]
    res = minimize_scalar(lambda t: -float(wall_force(system, sol.sol(t)[nb - 1], sol.sol(t)[2 * nb - 1])),
                          bounds=(lo, hi), method="bounded", options={"xatol": 1e-13})
    peak = max(-float(res.fun), float(fw[k]))
    return {"peak_wall_force": peak, "peak_wall_time": float(res.x), "nfev": int(sol.nfev)}


# ----------------------------------------------------------------------------- time to solution
def time_to_solution(model, duration: float, tolerance: float, repeat: int, repeat_scipy: int,
                     rhs_kinds: tuple[str, ...] = ("numpy", "compiled"), integrator: str = "verlet") -> dict:
    """Wall-clock time to get the peak wall force within ``tolerance`` (relative) of DOP853 rtol=1e-12.

    hertzchain: the whole ``simulate(model, duration)`` call with its automatic (adaptive) step and
    default probes (every contact force + energies every 100 ns, Dataset built). scipy:
    ``solve_ivp`` RK45 and DOP853 with rtol = 1e-4, 1e-5, ... (atol scaled alike) until the peak
    is within ``tolerance``; the state is sampled every 100 ns as well (:func:`solve_scipy`).
    ``speedup_vs_scipy`` is against the faster scipy solver with the NumPy right-hand side (what a
    user writes); ``speedup_vs_scipy_compiled_rhs`` against scipy driving hertzchain's compiled one;
    ``speedup_vs_dop853`` against DOP853 with the NumPy right-hand side. ``integrator``: the
    hertzchain integrator timed (``"verlet"`` or ``"rkn4"``, each at its default accuracy); the
    kernel alone is ``run_verlet`` / ``run_rkn`` with the same probes.
    """
    import hertzchain as hc
    from hertzchain.integrate.drivers.rkn import run_rkn
    from hertzchain.integrate.drivers.verlet import run_verlet

    system = model.system()
    t_ref, _, ref_ds = best_of(lambda: hc.simulate(model, duration, integrator="dop853", rtol=1e-12), 1)
    ref = float(ref_ds.attrs["peak_wall_force"])

    def rel(x: float) -> float:
        return abs(x / ref - 1.0)

    kernel = run_verlet if integrator == "verlet" else run_rkn
    hc.simulate(model, duration, integrator=integrator)  # warm
    t_hc, times_hc, ds = best_of(lambda: hc.simulate(model, duration, integrator=integrator), repeat)
    hc_peak = float(ds.attrs["peak_wall_force"])
    t_kernel, _, _ = best_of(lambda: kernel(system, duration, 1e-7), repeat)
    out = {"reference": {"integrator": "dop853", "rtol": 1e-12, "peak_wall_force": ref, "time_s": t_ref},
           "hertzchain": {"integrator": integrator, "time_s": t_hc, "times_s": times_hc,
                          "run_verlet_only_time_s": t_kernel, "kernel_only_time_s": t_kernel,
                          "simulate_outside_run_verlet_s": t_hc - t_kernel,
                          "simulate_outside_kernel_s": t_hc - t_kernel,
                          "time_step": ds.attrs.get("time_step", "fixed"), "dt": float(ds.attrs["dt"]),
                          "dt_max": float(ds.attrs.get("dt_max", ds.attrs["dt"])),
                          "n_steps": int(ds.attrs["n_steps"]), "peak_wall_force": hc_peak,
                          "rel_error": rel(hc_peak), "within_tolerance": rel(hc_peak) <= tolerance}}
    scipy_res = {}
    for rhs_kind in rhs_kinds:
        for method in ("RK45", "DOP853"):
            scan = []
            reached = None
            for e in range(4, 13):
                rtol = 10.0 ** -e
                t, _, r = best_of(lambda: solve_scipy(system, duration, method, rtol, rhs_kind), 1)
                scan.append({"rtol": rtol, "time_s": t, "peak_wall_force": r["peak_wall_force"],
                             "rel_error": rel(r["peak_wall_force"]), "nfev": r["nfev"]})
                if rel(r["peak_wall_force"]) <= tolerance:
                    reached = rtol
                    break
            entry = {"scan": scan, "rtol_reached": reached}
            if reached is not None:
                tb, tt, _ = best_of(lambda: solve_scipy(system, duration, method, reached, rhs_kind),
                                    max(0, repeat_scipy - 1))
                entry["time_s"] = min(tb, scan[-1]["time_s"])
                entry["times_s"] = [scan[-1]["time_s"]] + tt
                entry["rel_error"] = scan[-1]["rel_error"]
                entry["nfev"] = scan[-1]["nfev"]
            scipy_res[f"{method}_{rhs_kind}"] = entry
    out["scipy"] = scipy_res

    def fastest(kind: str) -> tuple[str | None, float]:
        cands = [(k, v["time_s"]) for k, v in scipy_res.items() if k.endswith(kind) and "time_s" in v]
        return min(cands, key=lambda kv: kv[1]) if cands else (None, float("nan"))

    for kind in rhs_kinds:
        name, t = fastest("_" + kind)
        suffix = "" if kind == "numpy" else "_" + kind + "_rhs"
        out[f"fastest_scipy_{kind}_rhs"] = name
        out["speedup_vs_scipy" + suffix] = t / t_hc
    dop = scipy_res.get("DOP853_numpy", {})
    out["speedup_vs_dop853"] = dop["time_s"] / t_hc if "time_s" in dop else float("nan")
    return out


def time_to_solution_rows(t: dict, tolerance: float) -> list[tuple]:
    """Table rows (solver, rtol, time ms, peak rel err, within, x slower) of :func:`time_to_solution`."""
    h = t["hertzchain"]
    step = (f"adaptive dt {h['dt'] * 1e9:.3g}-{h['dt_max'] * 1e9:.3g} ns" if h["time_step"] == "adaptive"
            else f"dt {h['dt'] * 1e9:.3g} ns")
    name = {"verlet": "Verlet", "rkn4": "rkn4"}.get(h.get("integrator", "verlet"), h.get("integrator"))
    rows = [(f"hertzchain {name} ({step}, {h['n_steps']} steps)", "-", f"{h['time_s'] * 1e3:.2f}",
             f"{h['rel_error']:.1e}", "yes" if h["within_tolerance"] else "NO", "1")]
    for k, v in t["scipy"].items():
        method, kind = k.split("_")
        name = f"scipy {method}, {'NumPy' if kind == 'numpy' else 'compiled'} RHS"
        if "time_s" in v:
            rows.append((name, f"{v['rtol_reached']:.0e}", f"{v['time_s'] * 1e3:.2f}", f"{v['rel_error']:.1e}", "yes",
                         f"{v['time_s'] / h['time_s']:.1f}"))
        else:
            rows.append((name, "not reached", "-", f"{v['scan'][-1]['rel_error']:.1e}", "NO", "-"))
    return rows
