"""What a user waits for: ``reproduce`` cold and warm, ``--from-data``, the first ``simulate``.

Every timing is the wall clock of a fresh process (as a user runs it), so it includes Python's
imports. "Cold" means an empty Numba cache (``NUMBA_CACHE_DIR`` pointed at a new folder: every
kernel is compiled); "warm" reuses the cache the previous runs filled. The baseline of
``--from-data`` in the same run is ``reproduce --no-figures`` (simulating everything, drawing
nothing), which issue 14 found faster than redrawing (6.2 s against 14.6 s). The CPU seconds of each command (all its
processes) are saved too: on a shared machine they vary less than the wall clock. About 2.5
minutes on 2 cores.

``--baseline-src DIR`` also times ``reproduce`` cold (its own empty Numba cache), ``--no-figures``
warm and ``--from-data`` with another version's ``src`` folder first on ``PYTHONPATH`` (the warm
ones alternated with this version's so that both see the same load), e.g. the version before a
change:

    git archive COMMIT src | tar -x -C /tmp/base
    .venv/bin/python benchmarks/ux_timings.py --baseline-src /tmp/base/src

    .venv/bin/python benchmarks/ux_timings.py [--json benchmarks/results/ux_timings.json] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import RESULTS, machine_info, save_json, table

#: The first simulate after import: the contract chain (19 beads, 2.5 ms, every contact recorded).
FIRST_SIMULATE = """
import time
t0 = time.perf_counter()
import hertzchain as hc
model = hc.Model(hc.Chain.from_diameters([x * 1e-3 for x in [26] * 16 + [24, 23, 22]]),
                 hc.Striker(8e-3, 0.5), hc.Wall("flat"), hc.Elastic())
t1 = time.perf_counter()
import warnings
warnings.simplefilter("ignore")
hc.simulate(model, 2.5e-3)
t2 = time.perf_counter()
import sys
print(t1 - t0, t2 - t1, int("scipy.integrate" in sys.modules))
"""


def _cli() -> list[str]:
    exe = Path(sys.executable).with_name("hertzchain")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "hertzchain.cli"]


#: CPU seconds (user + system, all processes) of every command _run timed, by label.
CPU: dict[str, list[float]] = {}


def _run(args: list[str], env: dict, label: str) -> float:
    """Wall-clock seconds of one command; its CPU seconds go to CPU[label] (less sensitive than
    the wall clock to the other users of a shared machine)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(args, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    CPU.setdefault(label, []).append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
    return wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path, default=RESULTS / "ux_timings.json")
    parser.add_argument("--repeat", type=int, default=3, help="repetitions of the warm timings (best is kept)")
    parser.add_argument("--baseline-src", type=Path, default=None,
                        help="src folder of another version: its --from-data is timed alternately with this one's")
    args = parser.parse_args()

    cli = _cli()
    results: dict = {"machine": machine_info()}
    with tempfile.TemporaryDirectory() as work:
        work = Path(work)
        cold_env = {**os.environ, "NUMBA_CACHE_DIR": str(work / "numba_cache")}
        out = work / "reproduction"
        # cold: empty Numba cache, every kernel compiled in this run
        results["reproduce_cold_s"] = _run([*cli, "reproduce", "--out", str(out)], cold_env, "reproduce_cold")
        base_env = None
        if args.baseline_src is not None:
            base_env = {**cold_env, "PYTHONPATH": str(args.baseline_src.resolve())}
            results["reproduce_cold_baseline_s"] = _run(
                [*cli, "reproduce", "--out", str(work / "base_cold")],
                {**base_env, "NUMBA_CACHE_DIR": str(work / "numba_cache_base")}, "reproduce_cold_baseline")
        warm = [_run([*cli, "reproduce", "--out", str(out)], cold_env, "reproduce_warm") for _ in range(max(1, args.repeat - 1))]
        results["reproduce_warm_s"] = min(warm)
        results["reproduce_warm_all_s"] = warm
        no_fig, no_fig_base = [], []
        for _ in range(max(1, args.repeat - 1)):  # alternated with the baseline's: both see the same load
            if base_env is not None:
                no_fig_base.append(_run([*cli, "reproduce", "--out", str(work / "nofig_base"), "--no-figures"],
                                        {**base_env, "NUMBA_CACHE_DIR": str(work / "numba_cache_base")},
                                        "no_figures_baseline"))
            no_fig.append(_run([*cli, "reproduce", "--out", str(work / "nofig"), "--no-figures"], cold_env, "no_figures"))
        results["reproduce_no_figures_warm_s"] = min(no_fig)
        if no_fig_base:
            results["reproduce_no_figures_warm_baseline_s"] = min(no_fig_base)
        redraw, base = [], []
        for _ in range(args.repeat):
            if base_env is not None:
                base.append(_run([*cli, "reproduce", "--out", str(out), "--from-data"], base_env, "from_data_baseline"))
            redraw.append(_run([*cli, "reproduce", "--out", str(out), "--from-data"], cold_env, "from_data"))
        results["from_data_s"] = min(redraw)
        results["from_data_all_s"] = redraw
        if base:
            results["from_data_baseline_s"] = min(base)
            results["from_data_baseline_all_s"] = base
            results["baseline_src"] = str(args.baseline_src)
        first = []
        for k in range(args.repeat + 1):
            env = {**os.environ, "NUMBA_CACHE_DIR": str(work / ("first_cold" if k == 0 else "numba_cache"))}
            line = subprocess.run([sys.executable, "-c", FIRST_SIMULATE], env=env, check=True,
                                  capture_output=True, text=True).stdout.split()
            first.append((float(line[0]), float(line[1]), int(line[2])))
        results["import_s"] = min(f[0] for f in first[1:])
        results["first_simulate_cold_s"] = first[0][1]
        results["first_simulate_warm_s"] = min(f[1] for f in first[1:])
        results["simulate_imports_scipy_integrate"] = bool(max(f[2] for f in first))

    results["cpu_s"] = {k: min(v) for k, v in CPU.items()}
    results["load_average_at_end"] = list(os.getloadavg())
    cpu = results["cpu_s"]
    rows = [("reproduce, cold (empty Numba cache): wall / CPU",
             f"{results['reproduce_cold_s']:.1f} s / {cpu['reproduce_cold']:.1f} s"),
            *([("reproduce, cold, baseline src: wall / CPU",
                f"{results['reproduce_cold_baseline_s']:.1f} s / {cpu['reproduce_cold_baseline']:.1f} s"),
               ("reproduce --no-figures, warm, baseline src: wall / CPU",
                f"{results['reproduce_no_figures_warm_baseline_s']:.1f} s / {cpu['no_figures_baseline']:.1f} s")]
              if base else []),
            ("reproduce, warm: wall / CPU", f"{results['reproduce_warm_s']:.1f} s / {cpu['reproduce_warm']:.1f} s"),
            ("reproduce --no-figures, warm (baseline): wall / CPU",
             f"{results['reproduce_no_figures_warm_s']:.1f} s / {cpu['no_figures']:.1f} s"),
            ("reproduce --from-data: wall / CPU", f"{results['from_data_s']:.1f} s / {cpu['from_data']:.1f} s"),
            *([("reproduce --from-data, baseline src: wall / CPU",
                f"{results['from_data_baseline_s']:.1f} s / {cpu['from_data_baseline']:.1f} s")] if base else []),
            ("import hertzchain", f"{results['import_s']:.2f} s"),
            ("first simulate after import, cold / warm cache",
             f"{results['first_simulate_cold_s']:.2f} s / {results['first_simulate_warm_s']:.2f} s"),
            ("simulate (Verlet) imports scipy.integrate", str(results["simulate_imports_scipy_integrate"]))]
    print(table(rows, ("quantity", "value")))
    save_json(results, args.json)
    print(f"saved {args.json}")


if __name__ == "__main__":
    main()
