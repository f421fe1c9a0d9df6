"""The explorer's page: controls on the left, the pictures of the view on the right (Panel on Bokeh).

Every control change recomputes the view (:func:`~hertzchain.explorer.compute.compute_view`, tens
of milliseconds for the paper's 30-bead chains) and replaces the data of the Bokeh plots in
place, so the browser redraws without reloading the page. Bokeh's and Panel's scripts are served
by the app itself: the page needs no network.
"""

from __future__ import annotations

import html
from functools import partial

import numpy as np
import panel as pn
from bokeh.models import ColorBar, ColumnDataSource, LinearColorMapper, Range1d
from bokeh.plotting import figure

from ..errors import HertzchainError
from .ballistic import RATIOS_NOTE
from .compute import ExplorerView, compute_view
from .settings import (CHAIN_KINDS, EPS_LAWS, LAWS, MAX_BODY_DURATION, STRIKER_SHAPES, WALLS, ExplorerSettings,
                       mount_half_period)

__all__ = ["Explorer"]

_PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#000000")
_ENERGIES = ("kinetic", "potential", "dissipated", "plastic", "total")


def _materials() -> list[str]:
    from ..materials import CATALOGUE

    return list(CATALOGUE)


def _readout(view: ExplorerView) -> str:
    """The line of numbers above the plots (HTML; the browser test reads the ``hc-*`` ids)."""
    res, s = view.result, view.settings
    parts = [f"{res.sizes['bead']} beads"]
    if "wall_force" in res:
        face = " on the body's face" if view.body_force is not None else ""
        parts.append(f"peak wall force{face} <b id='hc-peak'>{res.attrs['peak_wall_force']:.4g} N</b>")
    else:
        parts.append("peak wall force <b id='hc-peak'>no wall</b>")
    if view.body_force is not None:
        parts.append(f"peak body force (mount to ground) <b id='hc-body-peak'>{res.attrs['peak_body_force']:.4g} N</b>")
    fit = view.fit
    parts.append(f"cos<sup>6</sup> fit: F<sub>m</sub> = <b>{fit.peak_force:.4g} N</b>, "
                 f"T = <b>{fit.time_of_flight * 1e3:.4g} ms</b>, τ = <b>{fit.duration * 1e6:.4g} µs</b>"
                 if fit is not None else "no pulse found to fit")
    record = f"simulated to {res.attrs['duration'] * 1e3:.3g} ms"
    if view.body_force is not None and s.body_stiffness > 0:
        half = mount_half_period(s.body_mass, s.body_stiffness)
        record += f" (the mount's half period is {half * 1e3:.3g} ms"
        if res.attrs["duration"] >= MAX_BODY_DURATION:  # cut short (ExplorerSettings.config)
            record += ": <span style='color:#a00'>the record ends before the body's first swing is over</span>"
        record += ")"
    parts.append(f"{record}, computed in {view.seconds * 1e3:.0f} ms")
    if "plastic_work" in res:  # the elastoplastic law: how much of the striker's energy the yield took
        e0 = float(res.kinetic_energy.values[0])
        dent = res.residual_overlap  # per contact (contact_all), m
        parts.append(f"plastic work <b id='hc-plastic'>{res.attrs['plastic_work']:.3g} J</b> "
                     f"({res.attrs['plastic_work'] / e0:.1%} of the striker's energy); deepest residual overlap "
                     f"<b id='hc-residual'>{res.attrs['residual_overlap_max'] * 1e6:.3g} µm</b> "
                     f"(contact {int(dent.contact_all[int(np.argmax(dent.values))])})")
    elif res.attrs.get("elastic_limit_exceeded"):
        parts.append("<span style='color:#a00'>elastic limit passed: beads would yield</span>")
    return f"<div id='hc-readout'>{'; '.join(parts)}</div>"


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
            "uniform_n": w.IntSlider(label="uniform block: beads (0: no chain)", start=0, end=60, value=s.uniform_n),
            "uniform_diameter_mm": w.FloatInput(label="uniform block: diameter [mm]", value=s.uniform_diameter_mm,
                                                step=0.5),
            "taper_n": w.IntSlider(label="taper: beads n", start=0, end=40, value=s.taper_n),
            "taper_q": w.FloatSlider(label="taper: q", start=0.0, end=0.15, step=0.001, value=s.taper_q,
                                     format="0.000"),
            "diameters_mm": w.TextInput(label="per-bead diameters [mm]", value=s.diameters_mm),
            "material": w.Select(label="bead material", options=mats, value=s.material),
            "bead_materials": w.TextInput(label="per-bead materials (empty: all the same)", value=s.bead_materials,
                                          placeholder="e.g. AISI52100 x 28, brass x 2"),
            "gravity": w.FloatInput(label="gravity along the chain [m/s^2] (9.81: a column on the wall)",
                                    value=s.gravity, step=0.5),
            "striker_diameter_mm": w.FloatInput(label="striker diameter [mm]", value=s.striker_diameter_mm,
                                                step=0.5),
            "striker_velocity": w.FloatInput(label="striker velocity [m/s]", value=s.striker_velocity, step=0.05),
            "striker_material": w.Select(label="striker material", options=mats, value=s.striker_material),
            "striker_mass": w.FloatInput(label="striker mass [kg] (empty: the sphere's)", value=s.striker_mass,
                                         step=0.01, placeholder="the sphere's rho pi phi^3 / 6"),
            "striker_shape": w.Select(label="striker face", options=STRIKER_SHAPES, value=s.striker_shape),
            "wall": w.Select(label="wall", options=WALLS, value=s.wall),
            "wall_material": w.Select(label="wall material (the cap, or the body's face)", options=mats,
                                      value=s.wall_material),
            "body_mass": w.FloatInput(label="protected body: mass [kg]", value=s.body_mass, step=0.1),
            "body_stiffness": w.FloatInput(label="protected body: mount stiffness [N/m]", value=s.body_stiffness,
                                           step=1e5),
            "body_damping": w.FloatInput(label="protected body: mount damping [N s/m]", value=s.body_damping,
                                         step=10.0),
            "law": w.Select(label="contact law", options=LAWS, value=s.law),
            "eps": w.FloatSlider(label="per-bead factor eps (Sec. III)", start=0.9, end=1.0, step=0.001, value=s.eps,
                                 format="0.000"),
        }
        # The number boxes carry no bounds: Bokeh's box would clamp a typed -1 to its bound, or keep it
        # without telling the server; the config schema judges every value and the page names a refusal.
        for key, widget in self.widgets.items():
            # Sliders recompute when released (value_throttled), the rest on every committed change.
            prop = "value_throttled" if isinstance(widget, (w.IntSlider, w.FloatSlider)) else "value"
            widget.param.watch(lambda event, key=key: self._changed(key, event.new), prop)
        self.save = w.FileDownload(callback=self._toml_file, filename="explorer.toml", color="primary",
                                   label="save as config (TOML)")
        self.readout = pn.pane.HTML("", sizing_mode="stretch_width")
        self.message = pn.pane.HTML("", sizing_mode="stretch_width")  # a refused value, above the plots
        self._held: dict = {}  # boxes holding a refused value (see _from_boxes)
        self.theory = pn.pane.HTML("", sizing_mode="stretch_width")
        self._build_plots()
        self._update(compute_view(self.settings))
        self._visibility()
        controls = pn.Column(
            pn.pane.HTML("<h3>hertzchain explorer</h3>"),
            pn.pane.HTML("<b>Chain</b>"), *(self.widgets[k] for k in ("chain", "uniform_n", "uniform_diameter_mm",
                                                                     "taper_n", "taper_q", "diameters_mm", "material",
                                                                     "bead_materials", "gravity")),
            pn.pane.HTML("<b>Striker</b>"), *(self.widgets[k] for k in ("striker_diameter_mm", "striker_velocity",
                                                                       "striker_material", "striker_mass",
                                                                       "striker_shape")),
            pn.pane.HTML("<b>Wall</b>"), *(self.widgets[k] for k in ("wall", "wall_material", "body_mass",
                                                                    "body_stiffness", "body_damping")),
            pn.pane.HTML("<b>Contact law</b>"), self.widgets["law"], self.widgets["eps"],
            self.save, width=330)
        pictures = pn.Column(self.message, self.readout, pn.pane.Bokeh(self.wall_fig),
                             pn.Row(pn.pane.Bokeh(self.map_fig), pn.pane.Bokeh(self.energy_fig)), self.theory)
        self.layout = pn.Row(controls, pictures)

    def __panel__(self):
        return self.layout

    # -- the plots ------------------------------------------------------------------------------
    def _build_plots(self) -> None:
        self.wall_source = ColumnDataSource({"t": [], "force": []}, name="wall_source")
        self.fit_source = ColumnDataSource({"t": [], "force": []}, name="fit_source")
        self.body_source = ColumnDataSource({"t": [], "force": []}, name="body_source")
        fig = figure(width=760, height=300, x_axis_label="t [ms]", y_axis_label="F [N]",
                     title="wall force and the paper's cos^6 fit", tools="pan,wheel_zoom,box_zoom,reset,save")
        fig.line("t", "force", source=self.wall_source, line_width=1.5, color=_PALETTE[0],
                 legend_label="wall_force (simulated)")
        fig.line("t", "force", source=self.fit_source, line_width=2, color="#d62728", line_dash="dashed",
                 legend_label="F_m cos^6((t - T)/tau)")
        # with a protected body: what its mount passes to the ground (k x + c dx/dt), slower and smaller
        self.body_line = fig.line("t", "force", source=self.body_source, line_width=2, color=_PALETTE[2],
                                  legend_label="body_force (mount to ground)")
        fig.legend.location = "top_left"
        self.body_legend = fig.legend[0].items[-1]  # shown only with a protected body
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
        if view.signal != "wall_force":
            title = f"force at {view.signal} (free end) and the paper's cos^6 fit"
        elif view.body_force is not None:
            title = "force on the protected body's face (wall_force), its cos^6 fit, and the mount's body_force"
        else:
            title = "wall force and the paper's cos^6 fit"
        self.wall_fig.title.text = title
        self.wall_source.data = {"t": view.time * 1e3, "force": view.force}
        self.fit_source.data = {"t": view.fit_time * 1e3, "force": view.fit_force}
        body = view.body_force is not None
        self.body_source.data = {"t": view.time * 1e3 if body else [], "force": view.body_force if body else []}
        self.body_line.visible = body
        self.body_legend.visible = body
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
        self.readout.object = _readout(view)
        rows = "".join(f"<tr><td>{r.quantity}</td><td>{r.equation}</td><td>{r.theory}</td><td>{r.simulated}</td>"
                       f"<td style='font-size:85%'>{r.how}</td></tr>" for r in view.theory)
        self.theory.object = ("<b>Ballistic theory (paper Sec. III) beside the simulation</b>"
                              "<table id='hc-theory' style='border-collapse:collapse' border='1' cellpadding='4'>"
                              "<tr><th>quantity</th><th>from</th><th>theory</th><th>simulated</th>"
                              "<th>simulated: measured how</th></tr>"
                              f"{rows}</table><p style='font-size:85%;max-width:760px'>{RATIOS_NOTE}</p>")

    # -- controls -------------------------------------------------------------------------------
    def _visibility(self) -> None:
        kind = self.settings.chain
        for key in ("uniform_n", "uniform_diameter_mm", "taper_n", "taper_q"):
            self.widgets[key].visible = kind == "uniform"
        self.widgets["diameters_mm"].visible = kind == "diameters"
        self.widgets["wall_material"].visible = self.settings.wall in ("flat", "body")
        for key in ("body_mass", "body_stiffness", "body_damping"):
            self.widgets[key].visible = self.settings.wall == "body"
        self.widgets["eps"].visible = self.settings.law in EPS_LAWS

    def _changed(self, key: str, value) -> None:
        # Served, Panel may hand a box's change over outside Bokeh's document lock: a TextInput's
        # "enter-pressed" event coroutine runs the pending value change itself, unlocked, and writing
        # the plots' ColumnDataSources there raises "_pending_writes should be non-None" (the per-bead
        # diameters box failed so every time). pn.state.execute(schedule=True) runs the update on the
        # document's next tick, under its lock; without a server session (Jupyter) it runs at once.
        pn.state.execute(partial(self._from_boxes, key, value), schedule=True)

    def _from_boxes(self, key: str, value) -> None:
        """Apply a control's new value together with every box that still holds a refused one, so
        that the plots never show settings other than those in the boxes."""
        self._held[key] = value
        if self.apply(**self._held) is not None:
            self._held = {}

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
            self.message.object = (f"<p id='hc-message' style='color:#a00;font-weight:bold'>Not applied: "
                                   f"{html.escape(str(exc))}. The plots still show the last valid settings.</p>")
            return None
        self.settings = new
        self.message.object = ""
        self._visibility()
        self._update(view)
        return view

    def _toml_file(self):
        from io import BytesIO

        return BytesIO(self.settings.toml().encode("utf-8"))
