"""Figures as inline SVG text, written directly, the one plotting stack of every page: line charts
(linear or logarithmic axes), small multiples, grouped bars and histograms, deterministic for the
same data.

Written here rather than drawn with matplotlib: its layout (tick labels measured, tight bounding
boxes, a second draw for `bbox_inches`) cost 0.1 to 0.3 s per panel, over 5 s for the 45 panels
of kr500_rail's report, where these charts take milliseconds (`harness report --figures` draws the
same charts with matplotlib, for print: harness/report/figures.py). A series is thinned to what a
panel can show (the minimum and maximum of each pixel column, so a spike stays visible); a
non-finite value, or a non-positive one on a logarithmic axis, breaks the line.
"""

from __future__ import annotations

import functools
import html
import itertools
import math
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass

import numpy as np

WIDTH = 750  # px: the report's column
COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
          "#bcbd22", "#17becf")
FONT = 'font-family="sans-serif"'
CHAR = 0.58  # average glyph width in ems, to place legends without measuring text


@dataclass(frozen=True)
class Chart:
    """One chart as the report asked for it: the function (`kind`: lines, grid, bars, histograms) and
    its arguments, so that harness/report/figures.py draws the same data with matplotlib."""

    kind: str
    args: tuple
    kwargs: dict


_charts: ContextVar[list[Chart] | None] = ContextVar("charts", default=None)


@contextmanager
def collecting() -> Iterator[list[Chart]]:
    """Every chart drawn within, in the report's order."""
    charts: list[Chart] = []
    token = _charts.set(charts)
    try:
        yield charts
    finally:
        _charts.reset(token)


def _kept(draw):
    """A chart function whose calls are kept where `collecting` asks for them."""
    @functools.wraps(draw)
    def drawn(*args, **kwargs):
        charts = _charts.get()
        if charts is not None:
            charts.append(Chart(draw.__name__, args, kwargs))
        return draw(*args, **kwargs)
    return drawn


def _esc(s: str) -> str:
    return html.escape(str(s), quote=True)


def _fmt(v: float) -> str:
    if v == 0:
        return "0"
    a = abs(v)
    if a >= 1e4 or a < 1e-3:
        m, e = f"{v:.2e}".split("e")
        m = m.rstrip("0").rstrip(".")
        return f"{m}e{int(e)}"
    return f"{v:.4g}"


def _nice_ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    if not (np.isfinite(lo) and np.isfinite(hi)) or hi <= lo:
        return [lo] if np.isfinite(lo) else []
    raw = (hi - lo) / n
    mag = 10.0 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw)
    first = math.ceil(lo / step - 1e-9) * step
    return [first + k * step for k in range(int((hi - first) / step + 1e-9) + 1)]


class _Scale:
    """Data to pixels along one axis, linear or logarithmic."""

    def __init__(self, lo: float, hi: float, p0: float, p1: float, log: bool = False):
        self.log = log
        if log:
            lo, hi = math.log10(lo), math.log10(hi)
        if hi <= lo:  # a constant: centre it
            pad = abs(lo) * 0.05 or 1.0
            lo, hi = lo - pad, hi + pad
        self.lo, self.hi, self.p0, self.p1 = lo, hi, p0, p1

    def __call__(self, v: np.ndarray) -> np.ndarray:
        v = np.asarray(v, dtype=float)
        if self.log:
            with np.errstate(divide="ignore", invalid="ignore"):
                v = np.where(v > 0, np.log10(np.where(v > 0, v, 1.0)), np.nan)
        return self.p0 + (v - self.lo) / (self.hi - self.lo) * (self.p1 - self.p0)

    def ticks(self) -> list[float]:
        if not self.log:
            return _nice_ticks(self.lo, self.hi)
        first, last = math.ceil(self.lo - 1e-9), math.floor(self.hi + 1e-9)
        stride = max(1, math.ceil((last - first + 1) / 7))
        return [10.0**k for k in range(first, last + 1, stride)] or [10.0 ** round(self.lo)]


def _range(values: list[np.ndarray], log: bool) -> tuple[float, float]:
    v = np.concatenate([np.asarray(x, dtype=float).ravel() for x in values]) if values else np.array([])
    v = v[np.isfinite(v) & (v > 0)] if log else v[np.isfinite(v)]
    if not len(v):
        return (1.0, 10.0) if log else (0.0, 1.0)
    lo, hi = float(v.min()), float(v.max())
    if log:  # 5 % of the decades spanned at each end (a smallest bar stays visible)
        f = 10.0 ** (0.05 * max(math.log10(hi / lo), 1.0))
        return lo / f, hi * f
    pad = 0.05 * (hi - lo)
    return lo - pad, hi + pad


def thin(x: np.ndarray, y: np.ndarray, columns: int) -> tuple[np.ndarray, np.ndarray]:
    """At most two points per pixel column: each column's smallest and largest y, in time order."""
    n = len(x)
    if n <= 2 * columns:
        return x, y
    edges = np.linspace(0, n, columns + 1).astype(int)
    keep = []
    finite = np.isfinite(y)
    lo_key, hi_key = np.where(finite, y, np.inf), np.where(finite, y, -np.inf)
    for a, b in itertools.pairwise(edges):
        if b > a:
            i, j = a + int(np.argmin(lo_key[a:b])), a + int(np.argmax(hi_key[a:b]))
            keep.extend(sorted({i, j}))
    keep = np.array(keep)
    return x[keep], y[keep]


def _polyline(px: np.ndarray, py: np.ndarray, color: str, style: str, lw: float, ms: float) -> str:
    out = []
    ok = np.isfinite(px) & np.isfinite(py)
    if "o" in style:
        out += [f'<circle cx="{a:.1f}" cy="{b:.1f}" r="{ms:.1f}" fill="{color}"/>' for a, b in zip(px[ok], py[ok],
                                                                                                  strict=True)]
    if style.replace("o", "") or style == "-":
        dash = ' stroke-dasharray="5,3"' if "--" in style else (' stroke-dasharray="1.5,2"' if ":" in style else "")
        breaks = np.flatnonzero(~ok)
        for seg in np.split(np.arange(len(px)), breaks):
            seg = seg[ok[seg]]
            if len(seg) > 1:
                xy = np.column_stack([px[seg], py[seg]]).ravel().tolist()  # one printf for the whole line
                pts = ("%.1f,%.1f " * len(seg) % tuple(xy))[:-1]
                out.append(f'<polyline points="{pts}" fill="none" stroke="{color}" stroke-width="{lw}"{dash}/>')
    return "".join(out)


def flagged_spans(t: np.ndarray, flags: np.ndarray) -> list[tuple[float, float]]:
    """The flagged samples, consecutive ones as one band: each band's (start, end) times, half a step
    beyond its first and last sample."""
    dt = (t[1] - t[0]) if len(t) > 1 else 1.0
    f = np.concatenate([[False], np.asarray(flags, dtype=bool), [False]])
    starts, ends = np.flatnonzero(~f[:-1] & f[1:]), np.flatnonzero(f[:-1] & ~f[1:])
    return [(t[a] - dt / 2, t[b - 1] + dt / 2) for a, b in zip(starts, ends, strict=True)]


def _spans(t: np.ndarray, flags: np.ndarray, sx: _Scale, top: float, bottom: float) -> str:
    """Shade the flagged samples, consecutive ones as one band."""
    out = []
    for start, end in flagged_spans(t, flags):
        x0, x1 = sx(start), sx(end)
        out.append(f'<rect x="{x0:.1f}" y="{top:.1f}" width="{max(x1 - x0, 0.5):.1f}" height="{bottom - top:.1f}" '
                   f'fill="#d62728" fill-opacity="0.15"/>')
    return "".join(out)


def _legend(entries: list[tuple[str, str, str]], x: float, y: float, width: float,
            size: float = 9) -> tuple[str, float]:
    """(svg, height): entries (name, color, style) in rows from (x, y)."""
    out, cx, cy = [], x, y
    for name, color, style in entries:
        w = 22 + CHAR * size * len(name) + 12
        if cx > x and cx + w > x + width:
            cx, cy = x, cy + size + 5
        dash = ' stroke-dasharray="5,3"' if "--" in style else ""
        mark = (f'<circle cx="{cx + 9:.1f}" cy="{cy - size / 3:.1f}" r="2.5" fill="{color}"/>' if style == "o" else
                f'<line x1="{cx:.1f}" y1="{cy - size / 3:.1f}" x2="{cx + 18:.1f}" y2="{cy - size / 3:.1f}" '
                f'stroke="{color}" stroke-width="2"{dash}/>')
        out.append(mark + f'<text x="{cx + 22:.1f}" y="{cy:.1f}" font-size="{size}">{_esc(name)}</text>')
        cx += w
    return "".join(out), cy - y + size + 4


def _axes(box: tuple[float, float, float, float], sx: _Scale | None, sy: _Scale, title: str, ylabel: str,
          xlabel: str, size: float) -> str:
    """Frame, grid lines, tick labels and labels of the panel whose plotting area is box (x0, y0, x1, y1)."""
    x0, y0, x1, y1 = box
    out = [f'<rect x="{x0:.1f}" y="{y0:.1f}" width="{x1 - x0:.1f}" height="{y1 - y0:.1f}" fill="none" '
           f'stroke="#444" stroke-width="0.8"/>']
    for v in sx.ticks() if sx is not None else []:
        p = float(sx(v))
        if x0 - 0.5 <= p <= x1 + 0.5:
            out.append(f'<line x1="{p:.1f}" y1="{y0:.1f}" x2="{p:.1f}" y2="{y1:.1f}" stroke="#ccc" stroke-width="0.5"/>'
                       f'<text x="{p:.1f}" y="{y1 + size + 2:.1f}" font-size="{size}" text-anchor="middle">'
                       f'{_fmt(v)}</text>')
    for v in sy.ticks():
        p = float(sy(v))
        if y0 - 0.5 <= p <= y1 + 0.5:
            out.append(f'<line x1="{x0:.1f}" y1="{p:.1f}" x2="{x1:.1f}" y2="{p:.1f}" stroke="#ccc" stroke-width="0.5"/>'
                       f'<text x="{x0 - 3:.1f}" y="{p + size / 3:.1f}" font-size="{size}" text-anchor="end">'
                       f'{_fmt(v)}</text>')
    if title:
        out.append(f'<text x="{(x0 + x1) / 2:.1f}" y="{y0 - 5:.1f}" font-size="{size + 2}" text-anchor="middle">'
                   f'{_esc(title)}</text>')
    if ylabel:
        yc = (y0 + y1) / 2
        out.append(f'<text x="{x0 - 48:.1f}" y="{yc:.1f}" font-size="{size}" text-anchor="middle" '
                   f'transform="rotate(-90 {x0 - 48:.1f} {yc:.1f})">{_esc(ylabel)}</text>')
    if xlabel:
        out.append(f'<text x="{(x0 + x1) / 2:.1f}" y="{y1 + 2 * size + 6:.1f}" font-size="{size}" '
                   f'text-anchor="middle">{_esc(xlabel)}</text>')
    return "".join(out)


def _svg(width: float, height: float, body: str) -> str:
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{height:.0f}" '
            f'viewBox="0 0 {width:.0f} {height:.0f}" {FONT}>{body}</svg>')


def _panel(box, t, series: dict[str, np.ndarray], flags, styles, logy: bool, lw: float, ms: float, title: str,
           ylabel: str, xlabel: str, size: float, colors: dict[str, str], logx: bool = False) -> str:
    x0, y0, x1, y1 = box
    t = np.asarray(t, dtype=float)
    sx = (_Scale(float(t.min()), float(t.max()), x0, x1, log=logx) if len(t) and (not logx or t.min() > 0)
          else _Scale(0.0, 1.0, x0, x1))
    sy = _Scale(*_range(list(series.values()), logy), y1, y0, log=logy)
    body = [_axes(box, sx, sy, title, ylabel, xlabel, size)]
    if flags is not None and np.any(flags):
        body.append(_spans(t, flags, sx, y0, y1))
    for name, y in series.items():
        tt, yy = thin(t, np.asarray(y, dtype=float), int(x1 - x0))
        body.append(_polyline(sx(tt), np.clip(sy(yy), y0 - 2, y1 + 2), colors[name], (styles or {}).get(name, "-"),
                              lw, ms))
    return "".join(body)


def series_colors(names) -> dict[str, str]:
    """Each series name's colour, in order: the same in the SVG and in harness/report/figures.py."""
    return {name: COLORS[k % len(COLORS)] for k, name in enumerate(names)}


@_kept
def lines(t, series: dict[str, np.ndarray], ylabel: str, title: str, logy: bool = False,
          flags: np.ndarray | None = None, styles: dict[str, str] | None = None, height: float = 2.6,
          xlabel: str = "t [s]", logx: bool = False) -> str:
    """Series over one axis (time, unless `xlabel` says otherwise), one legend above."""
    colors = series_colors(series)
    heading = f'<text x="{WIDTH / 2:.1f}" y="16" font-size="12" text-anchor="middle">{_esc(title)}</text>'
    legend, lh = _legend([(k, colors[k], (styles or {}).get(k, "-")) for k in series], 70, 34, WIDTH - 80)
    h = 100 * height + lh
    box = (70, 30 + lh, WIDTH - 15, h - 40)
    return _svg(WIDTH, h, heading + legend + _panel(box, t, series, flags, styles, logy, 1.2, 2.5, "", ylabel,
                                                     xlabel, 10, colors, logx))


@_kept
def grid(t, panels: list[tuple[str, dict[str, np.ndarray], np.ndarray | None]], ylabel: str,
         logy: bool = False, styles: dict[str, str] | None = None, ncols: int = 2) -> str:
    """Small multiples: one panel per (title, series, flags), one legend above them."""
    names = list(dict.fromkeys(k for _, series, _ in panels for k in series))
    colors = series_colors(names)
    legend, lh = _legend([(k, colors[k], (styles or {}).get(k, "-")) for k in names], 60, 14, WIDTH - 70)
    nrows = -(-len(panels) // ncols)
    cell_w, cell_h = WIDTH / ncols, 170.0
    body = [legend]
    for k, (title, series, flags) in enumerate(panels):
        r, c = divmod(k, ncols)
        left, top = c * cell_w, lh + 10 + r * cell_h
        last_row = r == nrows - 1 or k + ncols >= len(panels)
        box = (left + 62, top + 20, left + cell_w - 12, top + cell_h - (40 if last_row else 22))
        body.append(_panel(box, t, series, flags, styles, logy, 1.1, 2.0, title, ylabel, "t [s]" if last_row else "",
                           8, colors))
    return _svg(WIDTH, lh + 10 + nrows * cell_h, "".join(body))


@_kept
def bars(labels: list[str], series: dict[str, list[float | None]], ylabel: str, title: str,
         logy: bool = True) -> str:
    colors = series_colors(series)
    heading = f'<text x="{WIDTH / 2:.1f}" y="16" font-size="12" text-anchor="middle">{_esc(title)}</text>'
    legend, lh = _legend([(k, colors[k], "-") for k in series], 70, 34, WIDTH - 80)
    longest = max((len(s) for s in labels), default=1)
    h = 234 + lh + 6 * CHAR * longest
    x0, y0, x1, y1 = 70, 34 + lh, WIDTH - 15, 34 + lh + 190
    values = {k: np.array([np.nan if v is None else abs(v) for v in vs], dtype=float) for k, vs in series.items()}
    sy = _Scale(*_range(list(values.values()), logy), y1, y0, log=logy)
    if not logy:  # bars grow from zero
        sy = _Scale(min(0.0, sy.lo), max(sy.hi, 0.0), y1, y0)
    n = max(1, len(labels))
    slot = (x1 - x0) / n
    width = 0.8 * slot / max(1, len(series))
    body = [heading, _axes((x0, y0, x1, y1), None, sy, "", ylabel, "", 10)]  # the categories are labelled below
    base = y1 if logy else float(sy(0.0))
    for k, (name, v) in enumerate(values.items()):
        for i, y in enumerate(v):
            if np.isfinite(y) and (y > 0 or not logy):
                top = float(np.clip(sy(y), y0, y1))
                xa = x0 + i * slot + 0.1 * slot + k * width
                body.append(f'<rect x="{xa:.1f}" y="{min(top, base):.1f}" width="{width:.1f}" '
                            f'height="{abs(base - top):.1f}" fill="{colors[name]}"/>')
    for i, lab in enumerate(labels):
        xc = x0 + (i + 0.5) * slot
        body.append(f'<text x="{xc:.1f}" y="{y1 + 4:.1f}" font-size="6" text-anchor="end" '
                    f'transform="rotate(-90 {xc:.1f} {y1 + 4:.1f})">{_esc(lab)}</text>')
    return _svg(WIDTH, h, "".join(body) + legend)


@_kept
def histograms(panels: list[tuple[str, np.ndarray]], xlabel: str, bins: int = 30, ncols: int = 6) -> str:
    """Small multiples: one histogram per (title, values), a line at zero where the range holds it."""
    nrows = -(-len(panels) // ncols)
    cell_w, cell_h = WIDTH / ncols, 110.0
    body = []
    for k, (title, values) in enumerate(panels):
        r, c = divmod(k, ncols)
        left, top = c * cell_w, r * cell_h
        box = (left + 30, top + 16, left + cell_w - 6, top + cell_h - 22)
        x0, y0, x1, y1 = box
        v = np.asarray(values, dtype=float)
        v = v[np.isfinite(v)]
        counts, edges = np.histogram(v, bins=bins) if len(v) else (np.zeros(bins), np.linspace(0.0, 1.0, bins + 1))
        sx = _Scale(float(edges[0]), float(edges[-1]), x0, x1)
        sy = _Scale(0.0, float(max(counts.max(), 1)), y1, y0)
        body.append(_axes(box, sx, sy, title, "", xlabel if r == nrows - 1 else "", 6))
        for n, a, b in zip(counts, edges[:-1], edges[1:], strict=True):
            if n:
                xa, xb, top_px = float(sx(a)), float(sx(b)), float(sy(n))
                body.append(f'<rect x="{xa:.1f}" y="{top_px:.1f}" width="{max(xb - xa - 0.3, 0.3):.1f}" '
                            f'height="{y1 - top_px:.1f}" fill="{COLORS[0]}"/>')
        if edges[0] <= 0.0 <= edges[-1]:
            z = float(sx(0.0))
            body.append(f'<line x1="{z:.1f}" y1="{y0:.1f}" x2="{z:.1f}" y2="{y1:.1f}" stroke="#000" '
                        'stroke-width="0.8"/>')
    return _svg(WIDTH, nrows * cell_h + 8, "".join(body))
