"""Scatter plots as inline SVG, drawn by hand: no plotting dependency, no external resources."""
from __future__ import annotations

from html import escape

import numpy as np

WIDTH, HEIGHT = 420, 260
LEFT, RIGHT, TOP, BOTTOM = 62, 12, 26, 40
MAX_POINTS = 1500


def _ticks(low: float, high: float, count: int = 5) -> np.ndarray:
    step = (high - low) / count
    magnitude = 10 ** np.floor(np.log10(step))
    step = min((m * magnitude for m in (1, 2, 5, 10) if m * magnitude >= step), default=step)
    return np.arange(np.ceil(low / step) * step, high + step * 1e-9, step)


def _range(values: np.ndarray) -> tuple[float, float]:
    low, high = float(np.min(values)), float(np.max(values))
    pad = (high - low) * 0.05 or max(abs(low) * 0.05, 1e-9)
    return low - pad, high + pad


def scatter(x: np.ndarray, y: np.ndarray, title: str, xlabel: str, ylabel: str, band: float | None = None,
            diagonal: bool = False) -> str:
    """An SVG scatter plot; `band` draws +-band as dashed lines (3 sigma), `diagonal` the line y = x."""
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = np.asarray(x)[keep], np.asarray(y)[keep]
    if x.size > MAX_POINTS:
        pick = np.linspace(0, x.size - 1, MAX_POINTS).round().astype(int)
        x, y = x[pick], y[pick]
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" class="plot" width="{WIDTH}" height="{HEIGHT}" '
             f'viewBox="0 0 {WIDTH} {HEIGHT}" role="img" aria-label="{escape(title)}">',
             f'<text x="{WIDTH / 2}" y="16" text-anchor="middle" class="title">{escape(title)}</text>']
    if x.size == 0:
        parts.append(f'<text x="{WIDTH / 2}" y="{HEIGHT / 2}" text-anchor="middle">no data</text></svg>')
        return "".join(parts)
    ys = np.concatenate([y, [band, -band]] if band else [y, x] if diagonal else [y])
    (x0, x1), (y0, y1) = _range(x), _range(ys)

    def px(v: np.ndarray) -> np.ndarray:
        return LEFT + (v - x0) / (x1 - x0) * (WIDTH - LEFT - RIGHT)

    def py(v: np.ndarray) -> np.ndarray:
        return HEIGHT - BOTTOM - (v - y0) / (y1 - y0) * (HEIGHT - TOP - BOTTOM)

    parts.append(f'<rect x="{LEFT}" y="{TOP}" width="{WIDTH - LEFT - RIGHT}" height="{HEIGHT - TOP - BOTTOM}" '
                 'fill="none" stroke="#888"/>')
    for t in _ticks(x0, x1):
        parts.append(f'<text x="{px(t):.1f}" y="{HEIGHT - BOTTOM + 14}" text-anchor="middle">{t:.4g}</text>')
    for t in _ticks(y0, y1):
        parts.append(f'<text x="{LEFT - 4}" y="{py(t) + 4:.1f}" text-anchor="end">{t:.4g}</text>')
    parts.append(f'<text x="{(LEFT + WIDTH - RIGHT) / 2}" y="{HEIGHT - 6}" text-anchor="middle">{escape(xlabel)}</text>')
    parts.append(f'<text x="12" y="{(TOP + HEIGHT - BOTTOM) / 2}" text-anchor="middle" '
                 f'transform="rotate(-90 12 {(TOP + HEIGHT - BOTTOM) / 2})">{escape(ylabel)}</text>')
    lines = [(x0, band, x1, band), (x0, -band, x1, -band)] if band else []
    lines += [(max(x0, y0), max(x0, y0), min(x1, y1), min(x1, y1))] if diagonal else []
    for a, b, c, d in lines:
        parts.append(f'<line x1="{px(a):.1f}" y1="{py(b):.1f}" x2="{px(c):.1f}" y2="{py(d):.1f}" '
                     'stroke="#c33" stroke-dasharray="4 3"/>')
    path = "".join(f"M{u:.1f} {v:.1f}h0.1" for u, v in zip(px(x), py(y)))
    parts.append(f'<path class="points" d="{path}" stroke="#236" stroke-width="2.2" stroke-linecap="round"/>')
    return "".join(parts) + "</svg>"
