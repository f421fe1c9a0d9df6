"""An ensemble's metrics: ``hertzchain summary`` (table + JSON) and ``hertzchain plot`` (histograms,
corner plot), checked against statistics computed independently on synthetic tables."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from hertzchain.cli.main import main
from hertzchain.viz.ensemble import corner_figure, histogram_figure

N = 500


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    """A metrics.csv as an ensemble writes it (no swept parameter), with known distributions:
    F_m ~ N(3.2 N, 0.05 N), T = 2.3 ms + 0.8 (F_m - 3.2) ms/N + noise (correlated with F_m),
    tau uniform; two members without a fitted pulse."""
    rng = np.random.default_rng(1)
    f = rng.normal(3.2, 0.05, N)
    t = 2.3e-3 + 0.8e-3 * (f - 3.2) + rng.normal(0, 2e-5, N)
    df = pd.DataFrame({"member": np.arange(N), "chunk": np.arange(N) // 100, "dt": 1e-8,
                       "peak_wall_force": f * 0.99, "peak_wall_time": t, "elastic_limit_exceeded": False,
                       "F_m": f, "T": t, "tau": rng.uniform(60e-6, 64e-6, N), "Q_F": 5.6e-4 + 0 * f,
                       "Q_T": 7.2e-4 + 0 * f, "kinetic_energy_end": 4e-5, "potential_energy_end": 2e-6,
                       "dissipated_energy_end": 1e-5, "force_over_yield": 0.35, "fit_error": ""})
    df.loc[[7, 9], ["F_m", "T", "tau", "Q_F", "Q_T"]] = np.nan
    df.loc[[7, 9], "fit_error"] = "no pulse: the record holds none"
    df.loc[[3], "elastic_limit_exceeded"] = True
    folder = tmp_path_factory.mktemp("ensemble")
    df.to_csv(folder / "metrics.csv", index=False)
    return folder, df


def test_histogram_counts_and_statistics_are_those_of_the_data(table, tmp_path):
    folder, df = table
    fig = histogram_figure(df, ["F_m", "T"], bins=25)
    ax_f, ax_t = fig.axes[:2]
    heights = np.array([p.get_height() for p in ax_f.patches])
    counts, edges = np.histogram(df["F_m"].dropna().to_numpy(), bins=25)  # independently, the same bins
    assert heights.sum() == N - 2 and np.array_equal(heights, counts)
    assert np.allclose([p.get_x() for p in ax_f.patches], edges[:-1], rtol=1e-12)
    assert ax_f.get_xlabel() == "F_m [N]" and ax_t.get_xlabel() == "T [ms]"
    # T drawn in ms: the bars hold the values times 1e3
    t_edges = np.array([p.get_x() for p in ax_t.patches])
    assert 2.1 < t_edges.min() < t_edges.max() < 2.5
    text = "\n".join(t.get_text() for t in ax_f.texts)
    f = df["F_m"].dropna().to_numpy()
    q05, q50, q95 = np.quantile(f, [0.05, 0.5, 0.95])
    for line in (f"n = {N - 2}", f"mean = {f.mean():.4g} N", f"std = {f.std(ddof=1):.4g} N", f"5 % = {q05:.4g}",
                 f"median = {q50:.4g}", f"95 % = {q95:.4g}"):
        assert line in text, (line, text)
    lines = sorted(line.get_xdata()[0] for line in ax_f.lines)  # mean, 5 %, median and 95 % marked
    assert np.allclose(lines, sorted([f.mean(), q05, q50, q95]))
    # the command: an ensemble's folder (or metrics.csv) draws the histogram of F_m by default
    assert main(["plot", str(folder), "--out", str(tmp_path / "h.png")]) == 0
    assert main(["plot", str(folder / "metrics.csv"), "--out", str(tmp_path / "t.svg"), "--signal", "T",
                 "--signal", "tau"]) == 0
    assert (tmp_path / "h.png").stat().st_size > 10_000 and "<svg" in (tmp_path / "t.svg").read_text()[:500]


def test_corner_plot_shows_the_correlation_and_every_member(table, tmp_path):
    folder, df = table
    fig = corner_figure(df, ["F_m", "T", "tau"], bins=20)
    axes = np.array(fig.axes).reshape(3, 3)
    ok = df[["F_m", "T", "tau"]].dropna()
    r = np.corrcoef(ok["F_m"], ok["T"])[0, 1]
    assert r > 0.8 and axes[0, 1].texts[0].get_text() == f"r = {r:.2f}"
    mesh = axes[1, 0].collections[0]  # the 2-D histogram of (F_m, T): every member in one cell
    assert mesh.get_array().sum() == len(ok)
    assert axes[2, 0].get_xlabel() == "F_m [N]" and axes[2, 2].get_xlabel() == "tau [us]"
    assert main(["plot", str(folder), "--kind", "corner", "--out", str(tmp_path / "c.png")]) == 0


def test_summary_prints_units_and_writes_the_statistics_as_json(table, tmp_path, capsys):
    folder, df = table
    assert main(["summary", str(folder), "--json", str(tmp_path / "s.json")]) == 0
    out = capsys.readouterr().out
    # The caption is wrapped at the terminal's width (COLUMNS): its words are checked, not its lines.
    flat = " ".join(out.split())
    assert "unit" in out and "median" in out and "95 %" in out and "2 without a fitted wall pulse" in flat
    assert "1 past the elastic limit" in flat
    row = next(line for line in out.splitlines() if line.strip().startswith("T "))
    assert " ms " in row  # T in milliseconds
    s = json.loads((tmp_path / "s.json").read_text())
    f = df["F_m"].dropna().to_numpy()
    m = s["metrics"]["F_m"]
    assert m["units"] == "N" and m["n"] == N - 2 and s["n_members"] == N and s["fit_failures"] == 2
    assert m["mean"] == pytest.approx(f.mean(), rel=1e-14) and m["std"] == pytest.approx(f.std(ddof=1), rel=1e-12)
    assert m["quantiles"]["0.95"] == pytest.approx(np.quantile(f, 0.95), rel=1e-14)
    assert s["metrics"]["T"]["units"] == "s" and "dt" not in s["metrics"]
    # default: FOLDER/summary.json; --signal picks metrics
    assert main(["summary", str(folder), "--signal", "tau", "-q"]) == 0
    assert list(json.loads((folder / "summary.json").read_text())["metrics"]) == ["tau"]


@pytest.mark.parametrize("args, field", [
    (["summary", "{folder}", "--signal", "speed"], "--signal"),
    (["plot", "{folder}", "--out", "{tmp}/x.png", "--signal", "speed"], "--signal"),
    (["plot", "{folder}", "--out", "{tmp}/x.png", "--kind", "corner", "--signal", "F_m"], "--signal"),
    (["plot", "{folder}", "--out", "{tmp}/x.png", "--kind", "energy"], "--kind"),
    (["summary", "{tmp}"], "metrics.csv"),
])
def test_user_errors_name_the_option_or_file(table, tmp_path, capsys, args, field):
    folder, _ = table
    argv = [a.format(folder=folder, tmp=tmp_path) for a in args]
    assert main(argv) == 2
    assert field in capsys.readouterr().err


@pytest.mark.parametrize("damage, line, why", [
    ("cell", 13, "column F_m holds 'abc', not a number"),
    ("ragged-last", N + 1, "fields, the header has 16"),
    ("long-line", 6, "17 fields, the header has 16"),
    ("flag", 4, "column elastic_limit_exceeded holds 'maybe', not true or false"),
])
def test_a_damaged_metrics_table_is_refused_naming_the_line(table, tmp_path, capsys, damage, line, why):
    """A cell 'abc' among F_m's numbers (which pandas would read as a text column, so that the
    metric vanished from the summary without a word), a ragged last line (half a member counted as
    one), a line with one field too many, a flag that is not true or false: exit 2, the file, the
    line and the column named; nothing summarised."""
    folder, _ = table
    rows = (folder / "metrics.csv").read_text().splitlines()
    header = rows[0].split(",")
    cells = [r.split(",") for r in rows[1:]]
    if damage == "cell":
        cells[line - 2][header.index("F_m")] = "abc"
    elif damage == "ragged-last":
        cells[-1] = cells[-1][:5]
    elif damage == "long-line":
        cells[line - 2].append("1.0")
    else:
        cells[line - 2][header.index("elastic_limit_exceeded")] = "maybe"
    damaged = tmp_path / "damaged"
    damaged.mkdir()
    (damaged / "metrics.csv").write_text("\n".join([rows[0], *(",".join(c) for c in cells)]) + "\n")
    assert main(["summary", str(damaged)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"metrics.csv: is damaged: line {line}: " in err and why in err, err
    assert "Traceback" not in err and not (damaged / "summary.json").exists()
