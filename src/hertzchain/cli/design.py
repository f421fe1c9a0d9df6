"""``hertzchain design``: search for the chain that best meets a goal.

Heavy imports (numba, cma, matplotlib) are deferred into the command so that ``hertzchain --help``
stays quick.
"""

from __future__ import annotations

from pathlib import Path

import click

from .common import dask_client, echo_warning, freeze_imports, require_device, set_option, laws_option


@click.command("design")
@laws_option
@click.argument("design_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "-o", "out", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Output folder: best.toml, design.json, history.csv, pareto.csv, design.html. Rerunning resumes.")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Dask scheduler address (e.g. tcp://host:8786): each generation is spread over its workers.")
@click.option("--force", is_flag=True, help="Start afresh when --out holds the checkpoint of a different design.")
@click.option("--no-html", is_flag=True, help="Skip design.html (figures).")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar or summary.")
@click.option("--device", type=click.Choice(["auto", "cpu", "cuda"]), default="auto", show_default=True,
              help="Where generations run: the CPU, the CUDA GPU (pip install \"hertzchain[gpu]\"), or auto (the "
                   "GPU when one is usable and a generation is large enough to gain).")
@set_option
def design(design_file: Path, out: Path, scheduler: str | None, force: bool, no_html: bool, quiet: bool,
           device: str, overrides: tuple[str, ...]) -> None:
    """Search the design space of DESIGN_FILE (TOML: [base] run config + [design] table).

    The search state is saved after every generation, so an interrupted design resumes when
    rerun with the same --out. --set paths are relative to [base] (e.g. --set striker.velocity=0.3).
    """
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from ..design import load_design, run_design, write_report

    from ..extras import require

    problem = load_design(design_file, overrides)
    require("design", "design", ("cma", "tomli_w"))  # before the search's imports: the extra, named
    _import_search()
    freeze_imports()
    require_device(device)  # fail now, naming the option, rather than in the first generation
    client = dask_client(scheduler)
    console = Console(stderr=True)
    try:
        if quiet:
            result = run_design(problem, out, client=client, force=force, device=device)
        else:
            console.print(f"design {design_file.name}: minimise {problem.objective_name} over {problem.space.dim} "
                          f"variables, budget {problem.section.budget} engine runs "
                          f"({'Dask at ' + scheduler if scheduler else 'local, all cores'})")
            with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                          console=console) as prog:
                task = prog.add_task("engine runs", total=problem.section.budget)

                def update(done: int, total: int) -> None:
                    prog.update(task, completed=done, total=total)

                result = run_design(problem, out, client=client, progress=update, force=force, device=device)
                if result.n_evaluations < problem.section.budget:  # ended before the budget: a full bar, not a cut one
                    prog.update(task, description="engine runs (search done within the budget)",
                                completed=result.n_evaluations, total=result.n_evaluations)
    finally:
        if client is not None:
            client.close()
    info = write_report(result, figures=not no_html)
    if quiet:
        if not info["best"]["feasible"]:
            echo_warning("no candidate met every constraint (best is the least infeasible)")
        return
    best = info["best"]
    value = best["objective"]
    units = info["units"]
    shown = (f"{value:.6g} {units[problem.objectives[0]]}" if not isinstance(value, dict)
             else ", ".join(f"{k} {v:.6g} {units[k]}" for k, v in value.items()))
    n_uniform = info["comparison"]["uniform"]["n_beads"]
    msg = (f"best {info['objective_label']}: {shown} ({info['n_evaluations']} engine runs, "
           f"{info['evaluations_per_s']:.0f}/s{', resumed' if result.resumed else ''}); "
           f"lower than the base configuration by {_improvement(info, 'base')}, than a uniform chain of {n_uniform} "
           f"beads by {_improvement(info, 'uniform')}"
           + (f", than no chain by {_improvement(info, 'no_chain')}" if "no_chain" in info["comparison"] else "")
           + f"; wrote {out}/")
    if not best["feasible"]:
        msg += "; warning: no candidate met every constraint (best is the least infeasible)"
    click.echo(msg)


def _import_search() -> None:
    """Import what the search runs on (the engine, CMA-ES, the first sample), so that
    :func:`~hertzchain.cli.common.freeze_imports` takes its modules out of the collector's reach too."""
    import cma  # noqa: F401
    from scipy.stats import qmc  # noqa: F401

    from ..design import search  # noqa: F401
    from ..runs import batch  # noqa: F401


def _improvement(info: dict, ref: str) -> str:
    imp = info["comparison"]["improvement_percent"][ref]
    breaks = info["comparison"][ref]["breaks"]
    # a reference that breaks the design's constraints is no alternative the search could have chosen
    said = f" (which breaks the constraints: {'; '.join(breaks)})" if breaks else ""
    if all(v is None for v in imp.values()):
        return "n/a" + (said or " (its pulse does not reach the wall within the run)")
    # (reference - best) / reference: positive when the design transmits less than the reference.
    return ", ".join("n/a" if v is None else f"{v:.1f} %" for v in imp.values()) + said
