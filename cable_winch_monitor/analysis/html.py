"""The compare report as one standalone HTML file: summary tables, failure regions, inline SVG plots."""
from __future__ import annotations

from html import escape
from pathlib import Path

import numpy as np

from .compare import THRESHOLD, Comparison
from .follows import NOTHING
from .svg import scatter

STYLE = ("body{font-family:sans-serif;margin:1.5em;color:#222}table{border-collapse:collapse;margin:.5em 0}"
         "td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}th{background:#eee}"
         ".plots{display:flex;flex-wrap:wrap;gap:6px}svg text{font-size:10px;font-family:sans-serif}"
         "svg .title{font-size:12px;font-weight:bold}")
UNITS = {"roll": "rad", "pitch": "rad", "depth": "m"}


def _unit(channel: str) -> str:
    return UNITS.get(channel, "N")


def _channel_plots(c: Comparison, index: int, name: str) -> str:
    seen = np.isfinite(c.data.measured[:, index])
    residual, measured = c.residuals[seen, index], c.data.measured[seen, index]
    unit, band = _unit(name), THRESHOLD * c.noise[index]
    payout = c.data.lengths[seen].mean(axis=1)
    plots = [scatter(c.data.times[seen], residual, f"{name}: residual vs time", "time [s]", f"residual [{unit}]", band),
             scatter(payout, residual, f"{name}: residual vs payout", "payout [m]", f"residual [{unit}]", band)]
    if name.startswith("tension_"):
        plots.append(scatter(measured, residual, f"{name}: residual vs tension", "measured tension [N]",
                             f"residual [{unit}]", band))
    plots.append(scatter(c.predicted[seen, index], measured, f"{name}: measured vs predicted",
                         f"predicted [{unit}]", f"measured [{unit}]", diagonal=True))
    return f"<h3>{escape(name)}</h3><div class='plots'>{''.join(plots)}</div>"


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
    """The report as an HTML document (no scripts, no external resources)."""
    rows = "".join(f"<tr><th>{escape(n)}</th><td>{s.count}</td><td>{s.rms:.4g}</td><td>{s.max_abs:.4g}</td>"
                   f"<td>{s.noise:.4g} ({escape(c.noise_source.get(n, ''))})</td><td>{s.score:.3f}</td></tr>"
                   for n, s in c.channels.items())
    regions = "".join(f"<li>{escape(r['description'])}</li>" for r in c.regions) or "<li>none</li>"
    effects = ", ".join(escape(repr(e)) for e in c.model.effects) or "none (rigid ropes)"
    plots = "".join(_channel_plots(c, c.data.channels.index(name), name) for name in c.channels)
    return ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>compare: "
            f"{escape(c.bag)}</title><style>{STYLE}</style></head><body>"
            f"<h1>Model versus measurement</h1><p>bag {escape(c.bag)}: {len(c.data)} measurement samples; "
            f"model effects: {effects}</p><p><b>score {c.score:.3f}</b> (noise-normalised RMS error; 1.0 = down to "
            "the sensor noise)</p><table><tr><th>channel</th><th>samples</th><th>RMS</th><th>max |error|</th>"
            f"<th>noise (source)</th><th>score</th></tr>{rows}</table>"
            f"<h2>Failure regions (|error| &gt; {THRESHOLD:g} sigma)</h2><ol>{regions}</ol>{_follows(c)}"
            f"<h2>Plots</h2>{plots}</body></html>")


def write_report(c: Comparison, path: str | Path) -> None:
    Path(path).write_text(render(c))
