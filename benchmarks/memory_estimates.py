"""Do the memory estimates hold? Peak resident memory of every documented example against its estimate.

For each example of ``examples/`` this script computes the estimate hertzchain makes before the
job starts (:func:`hertzchain.checks.estimate_resources` for a run, the sweep's
:func:`hertzchain.sweep.runner.estimate_sweep`, the design's pre-flight
(:func:`hertzchain.design.search.preflight`: its largest generation)), then runs
the job as documented (``hertzchain run / sweep / design``) in a fresh process and reads that
process's peak resident set size (``os.wait4``: the kernel's ``ru_maxrss``). The claim: every
ratio measured / estimated lies in [1/1.3, 1.3].

    .venv/bin/python benchmarks/memory_estimates.py            # every example (~3 min)
    .venv/bin/python benchmarks/memory_estimates.py chain1      # the examples whose name contains it

Prints a table and saves ``benchmarks/results/memory_estimates.json`` (``--json PATH``: elsewhere) with the
machine's description.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from _common import REPO, RESULTS, machine_info, save_json

BIN = Path(sys.executable).parent
EXAMPLES = REPO / "examples"
#: How each example is documented to run (README, the examples' headers).
RUNS = ["contract", "chain1", "chain1_elastic", "chain1_measured", "chain2", "chain2_elastic", "fig3c_dq_minus",
        "fig3c_dq_plus", "fig3c_reference", "lab_chain1"]
SWEEPS = ["sweep_taper", "tolerance_ensemble"]
DESIGNS = ["design_taper", "design_robust"]
#: The claim: measured peak / estimated peak within [1/TOLERANCE, TOLERANCE].
TOLERANCE = 1.3


def estimate(kind: str, path: Path):
    """The estimate hertzchain makes before running the example (a ResourceEstimate), as the fresh
    process that runs it makes it: the job on top of the engine's runtime (``RUNTIME_BYTES``;
    this script's own process holds more by then)."""
    from dataclasses import replace

    from hertzchain.checks import RUNTIME_BYTES

    return replace(_estimate(kind, path), process_bytes=RUNTIME_BYTES)


def _estimate(kind: str, path: Path):
    from hertzchain.checks import estimate_resources
    from hertzchain.config import build_model, build_probes, load_config
    from hertzchain.runs.simulation import auto_duration

    if kind == "run":
        cfg = load_config(path)
        model = build_model(cfg)
        duration = auto_duration(model) if cfg.run.duration == "auto" else cfg.run.duration
        return estimate_resources(model.system(), duration, build_probes(cfg), dt=cfg.run.dt,
                                  integrator=cfg.run.integrator)
    if kind == "sweep":
        from hertzchain.sweep import load_sweep
        from hertzchain.sweep.runner import estimate_sweep

        return estimate_sweep(load_sweep(path))
    from hertzchain.design import load_design
    from hertzchain.design.search import preflight

    return preflight(load_design(path))


def command(kind: str, path: Path, out: Path) -> list[str]:
    exe = str(BIN / "hertzchain")
    if kind == "run":
        return [exe, "run", str(path), "--out", str(out / "result.nc"), "-q"]
    if kind == "sweep":
        return [exe, "sweep", str(path), "--out", str(out / "sweep"), "-q"]
    return [exe, "design", str(path), "--out", str(out / "design"), "-q", "--no-html"]


def peak_rss(argv: list[str]) -> tuple[int, int, str]:
    """Run ``argv``; its peak resident set size [bytes], exit status and the end of its stderr."""
    with tempfile.TemporaryFile() as err:
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=err, cwd=REPO)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        return usage.ru_maxrss * 1024, proc.returncode, err.read().decode(errors="replace")[-500:]


def main(select: list[str], json_path: Path | None = None) -> int:
    """Every documented example (or those whose names contain one of ``select``); the results are
    saved (to ``json_path``, default results/memory_estimates.json) when every example ran or a
    path is given."""
    jobs = [("run", n) for n in RUNS] + [("sweep", n) for n in SWEEPS] + [("design", n) for n in DESIGNS]
    jobs = [j for j in jobs if not select or any(s in j[1] for s in select)]
    rows, failed = [], []
    print(f"{'example':22s} {'kind':6s} {'estimate MiB':>12s} {'(job)':>8s} {'peak RSS MiB':>12s} {'ratio':>6s}")
    for kind, name in jobs:
        path = EXAMPLES / f"{name}.toml"
        est = estimate(kind, path)
        with tempfile.TemporaryDirectory() as tmp:
            peak, status, err = peak_rss(command(kind, path, Path(tmp)))
        if status != 0:
            raise SystemExit(f"{name}: exit status {status}\n{err}")
        ratio = peak / est.peak_bytes
        ok = 1 / TOLERANCE <= ratio <= TOLERANCE
        rows.append({"example": name, "kind": kind, "estimate_bytes": est.peak_bytes, "job_bytes": est.memory_bytes,
                     "process_bytes": est.process_bytes, "peak_rss_bytes": peak, "ratio": ratio, "within": ok})
        if not ok:
            failed.append(name)
        print(f"{name:22s} {kind:6s} {est.peak_bytes / 2**20:12.0f} {est.memory_bytes / 2**20:8.0f} "
              f"{peak / 2**20:12.0f} {ratio:6.2f}{'' if ok else '  <-- outside'}")
    out = {"machine": machine_info(), "tolerance": TOLERANCE, "examples": rows, "all_within": not failed}
    if not select or json_path is not None:
        path = json_path or RESULTS / "memory_estimates.json"
        save_json(out, path)
        print(f"saved {path}")
    print("every estimate holds" if not failed else f"outside [1/{TOLERANCE}, {TOLERANCE}]: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", help="only the examples whose name contains one of these")
    ap.add_argument("--json", type=Path, help="where to save the results (default results/memory_estimates.json, "
                                              "written when every example ran)")
    args = ap.parse_args()
    sys.exit(main(args.names, args.json))
