"""Figures and files of ``compare`` and ``fit`` (every file written atomically via :mod:`hertzchain.fileio`)."""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path

from ..fileio import json_text, write_bytes, write_text

__all__ = ["figure_bytes", "plot_comparison", "plot_fit", "fit_html", "prepare_folder", "write_fit_outputs",
           "toml_text"]


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def figure_bytes(fig, fmt: str = "png") -> bytes:
    """Encode a Matplotlib figure and close it.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    fmt : str
        ``png``, ``pdf`` or ``svg``.

    Returns
    -------
    bytes
        The encoded image (150 dpi for PNG).
    """
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, dpi=150)
    _plt().close(fig)
    return buf.getvalue()


def plot_comparison(comp, out: str | Path, measured_label: str = "measured",
                    simulated_label: str = "simulated") -> Path:
    """Draw a comparison: both records [N] against the measured clock [ms], the residual underneath.

    Parameters
    ----------
    comp : Comparison
        What :func:`~hertzchain.lab.compare_traces` returned.
    out : str or os.PathLike
        Image file (``.png``, ``.pdf`` or ``.svg``), written atomically.
    measured_label, simulated_label : str
        Legend entries.

    Returns
    -------
    pathlib.Path
        ``out``.
    """
    plt = _plt()
    from ..viz.common import image_format

    out = Path(out)
    fmt = image_format(out)
    fig, (ax, axr) = plt.subplots(2, 1, sharex=True, figsize=(6.5, 4.8), gridspec_kw={"height_ratios": [3, 1]})
    t_ms = comp.time * 1e3
    ax.plot(t_ms, comp.measured_force, ".", ms=2.5, color="0.3", label=measured_label)
    ax.plot(t_ms, comp.simulated_force, lw=1.1, color="C3", label=f"{simulated_label} (shifted {comp.shift * 1e3:+.4g} ms)")
    ax.set_ylabel("F [N]")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(f"simulated - measured: dF_m = {comp.peak_force_diff:+.3g} N, "
                 f"dT = {comp.time_of_flight_diff * 1e6:+.3g} us, dtau = {comp.duration_diff * 1e6:+.3g} us, "
                 f"rms = {comp.rms_residual:.3g} N", fontsize=9)
    axr.plot(t_ms, comp.residual, lw=0.8, color="C0")
    axr.axhline(0, color="0.5", lw=0.6)
    axr.set_ylabel("simulated -\nmeasured [N]")
    axr.set_xlabel("t [ms] (measured clock)")
    for a in (ax, axr):
        a.grid(alpha=0.3)
    fig.tight_layout()
    write_bytes(out, figure_bytes(fig, fmt))
    return out


def plot_fit(result, fmt: str = "png") -> bytes:
    """Draw every trace with the fitted model [N] against time [ms], the residual underneath.

    Parameters
    ----------
    result : FitResult
        What :func:`~hertzchain.lab.fit_traces` returned.
    fmt : str
        Image format (``png``, ``pdf``, ``svg``).

    Returns
    -------
    bytes
        The encoded figure.
    """
    plt = _plt()
    K = len(result.traces)
    ncols = min(K, 3)
    nrows = -(-K // ncols)
    fig, axes = plt.subplots(2 * nrows, ncols, figsize=(4.2 * ncols, 3.4 * nrows), squeeze=False,
                             gridspec_kw={"height_ratios": [3, 1] * nrows})
    for k, tr in enumerate(result.traces):
        r, c = divmod(k, ncols)
        ax, axr = axes[2 * r, c], axes[2 * r + 1, c]
        t_ms = tr["time"] * 1e3
        ax.plot(t_ms, tr["data"], ".", ms=2, color="0.35", label="measured")
        ax.plot(t_ms, tr["model"], lw=1.0, color="C3", label="model")
        ax.set_title(f"{tr['name']} ({tr['signal']})", fontsize=8)
        ax.set_ylabel("F [N]", fontsize=8)
        axr.plot(t_ms, tr["residual"], lw=0.6, color="C0")
        axr.axhline(0, color="0.5", lw=0.5)
        axr.set_xlabel("t [ms]", fontsize=8)
        axr.set_ylabel("resid. [N]", fontsize=7)
        for a in (ax, axr):
            a.tick_params(labelsize=7)
            a.grid(alpha=0.3)
        if k == 0:
            ax.legend(fontsize=7, loc="upper right")
    for k in range(K, nrows * ncols):
        r, c = divmod(k, ncols)
        axes[2 * r, c].set_visible(False)
        axes[2 * r + 1, c].set_visible(False)
    fig.tight_layout()
    return figure_bytes(fig, fmt)


def fit_html(result, png: bytes) -> str:
    """A self-contained HTML report of a fit.

    Parameters
    ----------
    result : FitResult
        What :func:`~hertzchain.lab.fit_traces` returned.
    png : bytes
        The figure of :func:`plot_fit`, embedded in the page.

    Returns
    -------
    str
        The page: parameters with standard errors (and bootstrap spreads), correlations,
        goodness of fit, warnings and the figure.
    """
    e = html.escape
    boot = result.as_json()["parameters"]
    has_boot = bool(result.bootstrap.size)

    def boot_cells(n: str) -> str:
        if not has_boot:
            return ""
        b = boot[n]["bootstrap"]
        return f"<td>{b['stderr']:.2g}</td><td>[{b['interval_68'][0]:.6g}, {b['interval_68'][1]:.6g}]</td>"

    rows = "".join(f"<tr><td>{e(n)}</td><td>{e(boot[n]['unit'])}</td><td>{v:.6g}</td><td>{s:.2g}</td><td>{abs(s / v) * 100 if v else float('nan'):.2g} %</td>"
                   f"<td>{s0:.6g}</td>{boot_cells(n)}</tr>"
                   for n, v, s, s0 in zip(result.names, result.values, result.stderr, result.start))
    boot_head = (f"<th>bootstrap stderr ({result.bootstrap.shape[0]} refits)</th><th>bootstrap 68 % interval</th>"
                 if has_boot else "")
    head = "".join(f"<th>{e(n)}</th>" for n in result.names)
    corr = "".join("<tr><th>" + e(n) + "</th>" + "".join(f"<td>{c:+.3f}</td>" for c in row) + "</tr>"
                   for n, row in zip(result.names, result.correlation))
    traces = "".join(f"<tr><td>{e(t['name'])}</td><td>{e(t['signal'])}</td><td>{t['time'].size}</td>"
                     f"<td>{t['noise']:.3g}</td><td>{t['rms_residual']:.3g}</td></tr>" for t in result.traces)
    img = base64.b64encode(png).decode("ascii")
    return f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>hertzchain fit</title>
<style>body{{font-family:sans-serif;max-width:70em;margin:1em auto}} table{{border-collapse:collapse;margin:0.5em 0}}
td,th{{border:1px solid #ccc;padding:2px 8px;text-align:right}}</style></head><body>
<h1>hertzchain fit</h1>
<p>{'Converged' if result.converged else '<b>Not converged</b>'}: {e(result.message)}<br>
{''.join(f'<b>Warning:</b> {e(w)}<br>' for w in result.warnings)}
cost (half the sum of squared noise-weighted residuals) {result.cost:.6g}; {result.n_points} samples,
{len(result.names)} parameters; residual variance s<sup>2</sup> = {result.residual_variance:.4g} (1 when the
residuals are the noise); {result.n_evaluations} evaluations ({result.n_members} chains in batched engine calls,
{result.n_tangent_runs} tangent runs; Jacobian: {e(result.jacobian)}) in {result.elapsed:.2f} s.</p>
<h2>Parameters (SI units; standard errors from s<sup>2</sup> (J<sup>T</sup>J)<sup>-1</sup>)</h2>
<table><tr><th>parameter</th><th>unit</th><th>value</th><th>stderr</th><th>rel.</th><th>start</th>{boot_head}</tr>{rows}</table>
<h2>Correlations</h2><table><tr><th></th>{head}</tr>{corr}</table>
<h2>Traces</h2><table><tr><th>trace</th><th>signal</th><th>samples</th><th>noise [N]</th><th>rms residual [N]</th></tr>{traces}</table>
<h2>Traces, model and residuals</h2><img alt="fit" style="max-width:100%" src="data:image/png;base64,{img}">
</body></html>
"""


def toml_text(data: dict, header: str = "") -> str:
    """Write a run-config mapping as TOML text (``tomli_w``).

    Parameters
    ----------
    data : dict
        The mapping (as read from a TOML file, with changes).
    header : str
        Lines written first as ``#`` comments.

    Returns
    -------
    str
        TOML text that :func:`hertzchain.load_config` reads back to the same mapping.
    """
    from ..extras import require

    require("lab", "fit.toml", ("tomli_w",))
    import tomli_w

    lines = "".join(f"# {ln}\n" if ln else "#\n" for ln in header.splitlines())
    return lines + tomli_w.dumps(data)


def prepare_folder(out: str | Path) -> Path:
    """Create the output folder (and its parents) if needed.

    Parameters
    ----------
    out : str or os.PathLike
        The folder.

    Returns
    -------
    pathlib.Path
        ``out``.

    Raises
    ------
    ConfigError
        It cannot be created (a file in the way, no permission), naming ``--out``.
    """
    from ..errors import ConfigError

    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError("--out", f"{out}: cannot create the folder ({exc.strerror or exc})") from None
    return out


def write_fit_outputs(result, out: str | Path) -> dict[str, Path]:
    """Write ``fit.json``, ``calibrated.toml``, ``fit.png`` and ``fit.html`` into folder ``out``.

    Parameters
    ----------
    result : FitResult
        What :func:`~hertzchain.lab.fit_traces` returned.
    out : str or os.PathLike
        Folder (created when missing).

    Returns
    -------
    dict
        File kind -> path written.
    """
    out = prepare_folder(out)
    paths = {k: out / n for k, n in (("json", "fit.json"), ("toml", "calibrated.toml"), ("png", "fit.png"),
                                     ("html", "fit.html"))}
    write_text(paths["json"], json_text(result.as_json()) + "\n")
    meas = [f"  {n} = {v:.6g} +- {s:.2g}" for n, v, s in zip(result.names, result.values, result.stderr)
            if n.split("[")[0] in ("gain", "time_offset", "baseline")]
    header = ("Calibrated by hertzchain fit (values of the free config fields replaced by their best fit;\n"
              "see fit.json for standard errors and correlations).")
    if meas:
        header += "\nMeasurement parameters (not config fields):\n" + "\n".join(meas)
    write_text(paths["toml"], toml_text(result.config, header))
    png = plot_fit(result)
    write_bytes(paths["png"], png)
    write_text(paths["html"], fit_html(result, png))
    return paths
