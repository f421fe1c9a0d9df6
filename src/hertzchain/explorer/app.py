"""The explorer's page: controls on the left, the pictures of the view on the right (Panel on Bokeh).

Every control change recomputes the view (:func:`~hertzchain.explorer.compute.compute_view`, tens
of milliseconds for the paper's 30-bead chains) and replaces the data of the Bokeh plots in
place, so the browser redraws without reloading the page. Bokeh's and Panel's scripts are served
by the app itself: the page needs no network.
"""

from __future__ import annotations

import html

import numpy as np
import panel as pn
from bokeh.models import ColorBar, ColumnDataSource, LinearColorMapper, Range1d
from bokeh.plotting import figure

from ..errors import HertzchainError
from .compute import ExplorerView, compute_view
from .settings import CHAIN_KINDS, EPS_LAWS, LAWS, ExplorerSettings

__all__ = ["Explorer"]

_PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#000000")
_ENERGIES = ("kinetic", "potential", "dissipated", "plastic", "total")


def _materials() -> list[str]:
    from ..materials import CATALOGUE

    return list(CATALOGUE)


class Explorer(pn.viewable.Viewer):
    """The interactive explorer: a displayable Panel object (Jupyter) and the served app's page.

    Parameters
    ----------
    settings : ExplorerSettings or None
        The first view (default: the paper's chain 1 hit at 0.2 m/s, elastic contacts).
    **params
        Passed to :class:`panel.viewable.Viewer`.
    """

    def __init__(self, settings: ExplorerSettings | None = None, **params):
        super().__init__(**params)
        self.settings = settings or ExplorerSettings()
        self.view: ExplorerView | None = None
        s = self.settings
        mats = _materials()
        w = pn.widgets
        self.widgets = {
            "chain": w.Select(label="chain", options=CHAIN_KINDS, value=s.chain),
            "uniform_n": w.IntSlider(label="uniform block: beads", start=1, end=60, value=s.uniform_n),
            "uniform_diameter_mm": w.FloatInput(label="uniform block: diameter [mm]", value=s.uniform_diameter_mm,
                                                start=1.0, end=100.0, step=0.5),
            "taper_n": w.IntSlider(label="taper: beads n", start=0, end=40, value=s.taper_n),
            "taper_q": w.FloatSlider(label="taper: q", start=0.0, end=0.15, step=0.001, value=s.taper_q,
                                     format="0.000"),
            "diameters_mm": w.TextInput(label="per-bead diameters [mm]", value=s.diameters_mm),
            "material": w.Select(label="bead material", options=mats, value=s.material),
            "bead_materials": w.TextInput(label="per-bead materials (empty: all the same)", value=s.bead_materials,
                                          placeholder="e.g. AISI52100 x 28, brass x 2"),
            "striker_diameter_mm": w.FloatInput(label="striker diameter [mm]", value=s.striker_diameter_mm,
                                                start=0.5, end=100.0, step=0.5),
            "striker_velocity": w.FloatInput(label="striker velocity [m/s]", value=s.striker_velocity,
                                             start=0.001, end=10.0, step=0.05),
            "striker_material": w.Select(label="striker material", options=mats, value=s.striker_material),
            "wall": w.Select(label="wall", options={"flat wall (the paper's sensor cap)": "flat", "free end": "none"},
                             value=s.wall),
            "wall_material": w.Select(label="wall material", options=mats, value=s.wall_material),
            "law": w.Select(label="contact law", options=LAWS, value=s.law),
            "eps": w.FloatSlider(label="per-bead factor eps (Sec. III)", start=0.9, end=1.0, step=0.001, value=s.eps,
                                 format="0.000"),
        }
        for key, widget in self.widgets.items():
            # Sliders recompute when released (value_throttled), the rest on every committed change.
            prop = "value_throttled" if isinstance(widget, (w.IntSlider, w.FloatSlider)) else "value"
            widget.param.watch(lambda event, key=key: self._changed(key, event.new), prop)
        self.save = w.FileDownload(callback=self._toml_file, filename="explorer.toml", color="primary",
                                   label="save as config (TOML)")
        self.readout = pn.pane.HTML("", sizing_mode="stretch_width")
        self.message = pn.pane.HTML("", sizing_mode="stretch_width")
        self.theory = pn.pane.HTML("", sizing_mode="stretch_width")
        self._build_plots()
        self._update(compute_view(self.settings))
        self._visibility()
        controls = pn.Column(
            pn.pane.HTML("<h3>hertzchain explorer</h3>"),
            pn.pane.HTML("<b>Chain</b>"), *(self.widgets[k] for k in ("chain", "uniform_n", "uniform_diameter_mm",
                                                                     "taper_n", "taper_q", "diameters_mm", "material",
                                                                     "bead_materials")),
            pn.pane.HTML("<b>Striker</b>"), *(self.widgets[k] for k in ("striker_diameter_mm", "striker_velocity",
                                                                       "striker_material")),
            pn.pane.HTML("<b>Wall</b>"), self.widgets["wall"], self.widgets["wall_material"],
            pn.pane.HTML("<b>Contact law</b>"), self.widgets["law"], self.widgets["eps"],
            self.save, self.message, width=330)
        pictures = pn.Column(self.readout, pn.pane.Bokeh(self.wall_fig), pn.Row(pn.pane.Bokeh(self.map_fig),
                                                                               pn.pane.Bokeh(self.energy_fig)),
                             self.theory)
        self.layout = pn.Row(controls, pictures)

    def __panel__(self):
        return self.layout

    # -- the plots ------------------------------------------------------------------------------
    def _build_plots(self) -> None:
        self.wall_source = ColumnDataSource({"t": [], "force": []}, name="wall_source")
        self.fit_source = ColumnDataSource({"t": [], "force": []}, name="fit_source")
        fig = figure(width=760, height=300, x_axis_label="t [ms]", y_axis_label="F [N]",
                     title="wall force and the paper's cos^6 fit", tools="pan,wheel_zoom,box_zoom,reset,save")
        fig.line("t", "force", source=self.wall_source, line_width=1.5, color=_PALETTE[0], legend_label="simulated")
        fig.line("t", "force", source=self.fit_source, line_width=2, color="#d62728", line_dash="dashed",
                 legend_label="F_m cos^6((t - T)/tau)")
        fig.legend.location = "top_left"
        self.wall_fig = fig

        self.map_source = ColumnDataSource({"image": [], "x": [], "y": [], "dw": [], "dh": []}, name="map_source")
        self.mapper = LinearColorMapper(palette="Magma256", low=0.0, high=1.0, high_color="black")
        self.mapper.palette = list(reversed(self.mapper.palette))
        fig = figure(width=420, height=340, x_axis_label="contact j (0 = striker-bead 1)", y_axis_label="t [ms]",
                     title="space-time map of the contact forces", tools="pan,wheel_zoom,box_zoom,reset,save")
        fig.image("image", x="x", y="y", dw="dw", dh="dh", source=self.map_source, color_mapper=self.mapper)
        fig.add_layout(ColorBar(color_mapper=self.mapper, title="F [N]"), "right")
        self.map_x, self.map_y = Range1d(0, 1), Range1d(0, 1)
        fig.x_range, fig.y_range = self.map_x, self.map_y
        self.map_fig = fig

        self.energy_source = ColumnDataSource({"t": [], **{name: [] for name in _ENERGIES}}, name="energy_source")
        fig = figure(width=340, height=340, x_axis_label="t [ms]", y_axis_label="energy [mJ]", title="energies",
                     tools="pan,wheel_zoom,box_zoom,reset,save")
        for colour, name in zip(_PALETTE, _ENERGIES):
            fig.line("t", name, source=self.energy_source, color=colour, line_width=1.5, legend_label=name)
        fig.legend.location = "center"
        self.energy_fig = fig

    def _update(self, view: ExplorerView) -> None:
        """Put ``view`` on the page: new data in the plots' sources, new text."""
        self.view = view
        self.wall_fig.title.text = ("wall force and the paper's cos^6 fit" if view.signal == "wall_force"
                                    else f"force at {view.signal} (free end) and the paper's cos^6 fit")
        self.wall_source.data = {"t": view.time * 1e3, "force": view.force}
        self.fit_source.data = {"t": view.fit_time * 1e3, "force": view.fit_force}
        x, t, f = view.map_x, view.map_time, view.map_force
        dx = float(x[1] - x[0]) if x.size > 1 else 1.0
        dt = float(t[1] - t[0]) if t.size > 1 else 1e-6
        self.map_source.data = {"image": [np.ascontiguousarray(f)], "x": [float(x[0]) - 0.5 * dx],
                                "y": [float(t[0]) * 1e3], "dw": [dx * x.size], "dh": [dt * t.size * 1e3]}
        self.mapper.high = max(view.map_vmax, 1e-12)
        self.map_x.start, self.map_x.end = float(x[0]) - 0.5 * dx, float(x[-1]) + 0.5 * dx
        self.map_y.start, self.map_y.end = float(t[0]) * 1e3, float(t[0] + dt * t.size) * 1e3
        data = {"t": view.energy_time * 1e3}
        data.update({name: e * 1e3 for name, e in view.energies})
        for name in _ENERGIES:
            data.setdefault(name, np.full(view.energy_time.size, np.nan))
        self.energy_source.data = data
        res = view.result
        peak = f"{res.attrs['peak_wall_force']:.4g} N" if "wall_force" in res else "no wall"
        fit = view.fit
        fit_text = (f"F<sub>m</sub> = <b>{fit.peak_force:.4g} N</b>, T = <b>{fit.time_of_flight * 1e3:.4g} ms</b>, "
                    f"τ = <b>{fit.duration * 1e6:.4g} µs</b>" if fit is not None else "no pulse found to fit")
        limit = ""
        if "plastic_work" in res:  # the elastoplastic law: how much of the striker's energy the yield took
            e0 = float(sum(e[0] for name, e in view.energies if name != "total"))
            limit = f"; plastic work <b>{float(res.plastic_work[-1]) / e0:.1%}</b> of the striker's energy"
        elif res.attrs.get("elastic_limit_exceeded"):
            limit = " <span style='color:#a00'>elastic limit passed: beads would yield</span>"
        self.readout.object = (f"<div id='hc-readout'>{res.sizes['bead']} beads; peak wall force "
                               f"<b id='hc-peak'>{peak}</b>; cos<sup>6</sup> fit: {fit_text}; "
                               f"computed in {view.seconds * 1e3:.0f} ms{limit}</div>")
        rows = "".join(f"<tr><td>{r.quantity}</td><td>{r.equation}</td><td>{r.theory}</td><td>{r.simulated}</td></tr>"
                       for r in view.theory)
        self.theory.object = ("<b>Ballistic theory (paper Sec. III) beside the simulation</b>"
                              "<table style='border-collapse:collapse' border='1' cellpadding='4'>"
                              "<tr><th>quantity</th><th>from</th><th>theory</th><th>simulated</th></tr>"
                              f"{rows}</table>")

    # -- controls -------------------------------------------------------------------------------
    def _visibility(self) -> None:
        kind = self.settings.chain
        for key in ("uniform_n", "uniform_diameter_mm", "taper_n", "taper_q"):
            self.widgets[key].visible = kind == "uniform"
        self.widgets["diameters_mm"].visible = kind == "diameters"
        self.widgets["wall_material"].visible = self.settings.wall == "flat"
        self.widgets["eps"].visible = self.settings.law in EPS_LAWS

    def _changed(self, key: str, value) -> None:
        self.apply(**{key: value})

    def apply(self, **changes) -> ExplorerView | None:
        """Change settings and recompute the view (what a control does).

        Parameters
        ----------
        **changes
            :class:`ExplorerSettings` fields and their new values.

        Returns
        -------
        ExplorerView or None
            The new view; None when a value was refused (the message is shown, the view kept).
        """
        new = self.settings.replace(**changes)
        try:
            view = compute_view(new)
        except (HertzchainError, TypeError, ValueError) as exc:  # a value refused, or an emptied field
            self.message.object = f"<p style='color:#a00'>{html.escape(str(exc))}</p>"
            return None
        self.settings = new
        self.message.object = ""
        self._visibility()
        self._update(view)
        return view

    def _toml_file(self):
        from io import BytesIO

        return BytesIO(self.settings.toml().encode("utf-8"))
