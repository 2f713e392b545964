"""The compare report as one self-contained HTML file: summary tables, failure regions, interactive plotly plots.

plotly.js is embedded once in the file, so the report opens offline (a mine site has no
internet) in any browser, with zoom, pan and hover. Time is in seconds from the start of
the recording; every residual is coloured by what the winches were doing (lowering,
hoisting, shifting, standing: analysis.motion); failure regions are shaded on the time axes and listed with the
share of each motion they span. Every point is drawn: nothing is thinned.
"""
from __future__ import annotations

from datetime import UTC, datetime
from html import escape
from pathlib import Path

import numpy as np
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from ..channels import TENSION_CHANNELS
from .compare import THRESHOLD, Comparison
from .follows import NOTHING
from .motion import MOTIONS, motions

STYLE = ("body{font-family:sans-serif;margin:1.5em;color:#222}table{border-collapse:collapse;margin:.5em 0}"
         "td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}th{background:#eee}"
         ".region{background:#fde2e2}")
MOTION_COLOURS = {"lowering": "#1f77b4", "hoisting": "#ff7f0e", "shifting": "#2ca02c", "standing": "#7f7f7f"}
REGION_COLOUR = "#d62728"
EPOCH_AFTER = 1e8  # [s] stamps beyond this are clock time (a real recording), not simulation time from 0


def time_axis_title(start: float) -> str:
    """The time axis: seconds from the first measurement, with its clock time for a real recording."""
    if start > EPOCH_AFTER:
        clock = datetime.fromtimestamp(start, tz=UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
        return f"time from the start of the recording ({clock}) [s]"
    return "time from the start of the recording [s]"


def _shade_regions(fig: go.Figure, c: Comparison, **where: int) -> None:
    for number, region in enumerate(c.regions, 1):
        fig.add_vrect(x0=region["start"], x1=region["end"], fillcolor=REGION_COLOUR, opacity=0.12,
                      line_width=0, annotation_text=f"R{number}", annotation_position="top left",
                      annotation_font_size=10, **where)


def _channel_figure(c: Comparison, index: int, name: str, kinds: np.ndarray, start: float) -> go.Figure:
    """Residual against time, payout and (load pins) tension, and measured against predicted, by motion."""
    seen = np.isfinite(c.data.measured[:, index])
    residual, measured = c.residuals[:, index], c.data.measured[:, index]
    unit, band = c.model.channels.get(name).unit, THRESHOLD * c.noise[index]
    times, payout = c.data.times - start, c.data.lengths.mean(axis=1)
    panels = [("time", times, time_axis_title(start)), ("payout", payout, "payout [m]")]
    if name in TENSION_CHANNELS:
        panels.append(("tension", measured, "measured tension [N]"))
    fig = make_subplots(rows=1, cols=len(panels) + 1, horizontal_spacing=0.06,
                        subplot_titles=[f"residual vs {label}" for label, *_ in panels] + ["measured vs predicted"])
    for motion_index, motion in enumerate(MOTIONS):
        rows = seen & (kinds == motion_index)
        custom = np.column_stack([times[rows], payout[rows]])
        hover = (f"{motion}<br>t = %{{customdata[0]:.2f}} s<br>payout %{{customdata[1]:.3f}} m"
                 f"<br>residual %{{y:.4g}} {unit}<extra>{escape(name)}</extra>")
        for col, (_, x, _) in enumerate(panels, 1):
            fig.add_trace(go.Scatter(x=x[rows], y=residual[rows], mode="markers", name=motion, legendgroup=motion,
                                     showlegend=col == 1, marker={"size": 3, "color": MOTION_COLOURS[motion]},
                                     customdata=custom, hovertemplate=hover), row=1, col=col)
        fig.add_trace(go.Scatter(x=c.predicted[rows, index], y=measured[rows], mode="markers", name=motion,
                                 legendgroup=motion, showlegend=False,
                                 marker={"size": 3, "color": MOTION_COLOURS[motion]}, customdata=custom,
                                 hovertemplate=f"{motion}<br>t = %{{customdata[0]:.2f}} s<br>predicted %{{x:.6g}}"
                                 f"<br>measured %{{y:.6g}} {unit}<extra>{escape(name)}</extra>"),
                      row=1, col=len(panels) + 1)
    for col, (_, _, title) in enumerate(panels, 1):
        for level in (band, -band):
            fig.add_hline(y=level, line_dash="dash", line_color=REGION_COLOUR, line_width=1, row=1, col=col)
        fig.update_xaxes(title_text=title, row=1, col=col)
        fig.update_yaxes(title_text=f"residual [{unit}]", row=1, col=col)
    _shade_regions(fig, c, row=1, col=1)
    predicted = c.predicted[seen, index]
    if predicted.size and np.isfinite(predicted).any():
        low, high = float(np.nanmin(predicted)), float(np.nanmax(predicted))
        fig.add_trace(go.Scatter(x=[low, high], y=[low, high], mode="lines", showlegend=False, hoverinfo="skip",
                                 line={"color": "#444", "dash": "dot", "width": 1}), row=1, col=len(panels) + 1)
    fig.update_xaxes(title_text=f"predicted [{unit}]", row=1, col=len(panels) + 1)
    fig.update_yaxes(title_text=f"measured [{unit}]", row=1, col=len(panels) + 1)
    fig.update_layout(title_text=f"{name}  (dashed: +-{THRESHOLD:g} sigma; shaded: failure regions)",
                      height=360, margin={"l": 60, "r": 20, "t": 60, "b": 50}, legend={"itemsizing": "constant"})
    return fig


def _overview(c: Comparison, kinds: np.ndarray, start: float) -> go.Figure:
    """Every channel's error in sigma against time, with the failure regions: where the model misses, at a glance."""
    fig = go.Figure()
    z = c.residuals / c.noise
    times = c.data.times - start
    for index, name in enumerate(c.data.channels):
        rows = np.isfinite(z[:, index])
        if not rows.any():
            continue
        motion = np.array(MOTIONS)[kinds[rows]]
        fig.add_trace(go.Scatter(x=times[rows], y=z[rows, index], mode="markers", name=name,
                                 marker={"size": 3}, customdata=motion,
                                 hovertemplate="t = %{x:.2f} s<br>%{y:.2f} sigma<br>%{customdata}"
                                 f"<extra>{escape(name)}</extra>"))
    for level in (THRESHOLD, -THRESHOLD):
        fig.add_hline(y=level, line_dash="dash", line_color=REGION_COLOUR, line_width=1)
    _shade_regions(fig, c)
    fig.update_layout(title_text="error of every channel in units of its noise", height=380,
                      xaxis_title=time_axis_title(start), yaxis_title="residual / noise [sigma]",
                      margin={"l": 60, "r": 20, "t": 50, "b": 50}, legend={"itemsizing": "constant"})
    return fig


def _region_rows(c: Comparison) -> str:
    rows = []
    for number, r in enumerate(c.regions, 1):
        share = " / ".join(f"{100.0 * r['motion'][m]:.0f} %" for m in MOTIONS)
        rows.append(f"<tr class='region'><th>R{number}</th><td>{r['start']:.1f}-{r['end']:.1f}</td>"
                    f"<td>{share}</td><td style='text-align:left'>{escape(r['description'])}</td></tr>")
    header = (f"<tr><th>region</th><th>time [s]</th><th>{' / '.join(MOTIONS)}</th>"
              "<th>what the plant was doing, which channels miss</th></tr>")
    return f"<table>{header}{''.join(rows)}</table>" if rows else "<p>none</p>"


def _follows(c: Comparison) -> str:
    """What the remaining error follows: one row per finding."""
    rows = "".join(f"<tr><th>{escape(f.target)}</th><td>{escape(f.regressor)}</td><td>{f.measure} = {f.r:.2f}</td>"
                   f"<td>{f.n}</td><td>{f.n_eff:.0f}</td><td style='text-align:left'>{escape(f.sentence)}</td></tr>"
                   for f in c.follows)
    table = (f"<table><tr><th>residual</th><th>follows</th><th>r</th><th>n</th><th>independent</th><th>in words"
             f"</th></tr>{rows}</table>" if rows else f"<p>{escape(NOTHING)}</p>")
    notes = "".join(f"<li>{escape(note)}</li>" for note in c.follows_notes)
    return f"<h2>What the remaining error follows</h2>{table}" + (f"<ul>{notes}</ul>" if notes else "")


def render(c: Comparison) -> str:
    """The report as one HTML document: plotly.js inline, no external resources."""
    start = float(c.data.times[0]) if len(c.data) else 0.0
    kinds = motions(c.data.speeds)
    rows = "".join(f"<tr><th>{escape(n)}</th><td>{s.count}</td><td>{s.rms:.4g}</td><td>{s.max_abs:.4g}</td>"
                   f"<td>{s.noise:.4g} ({escape(c.noise_source.get(n, ''))})</td><td>{s.score:.3f}</td></tr>"
                   for n, s in c.channels.items())
    effects = ", ".join(escape(repr(e)) for e in c.model.effects) or "none (rigid ropes)"
    figures = [_overview(c, kinds, start)] + [_channel_figure(c, c.data.channels.index(name), name, kinds, start)
                                              for name in c.channels]
    plots = "".join(fig.to_html(full_html=False, include_plotlyjs=k == 0, config={"displaylogo": False})
                    for k, fig in enumerate(figures))
    return ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>compare: "
            f"{escape(c.bag)}</title><style>{STYLE}</style></head><body>"
            f"<h1>Model versus measurement</h1><p>bag {escape(c.bag)}: {len(c.data)} measurement samples over "
            f"{(c.data.times[-1] - start) if len(c.data) else 0.0:.1f} s; model effects: {effects}</p>"
            f"<p><b>score {c.score:.3f}</b> (noise-normalised RMS error; 1.0 = down to the sensor noise)</p>"
            "<table><tr><th>channel</th><th>samples</th><th>RMS</th><th>max |error|</th>"
            f"<th>noise (source)</th><th>score</th></tr>{rows}</table>"
            f"<h2>Failure regions (|error| &gt; {THRESHOLD:g} sigma)</h2>{_region_rows(c)}{_follows(c)}"
            "<h2>Plots</h2><p>Drag to zoom, double-click to reset, hover for values; click a motion in a legend to "
            f"hide it.</p>{plots}</body></html>")


def write_report(c: Comparison, path: str | Path) -> None:
    Path(path).write_text(render(c), encoding="utf-8")
