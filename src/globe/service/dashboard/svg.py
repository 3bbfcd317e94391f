"""The dashboard's charts, drawn here as SVG text (no chart library, nothing fetched), inline in the
HTML (so without an xmlns: the HTML parser places them).

Colours are presentation attributes (``fill``, ``fill-opacity``), never ``style``, so the pages
keep a Content-Security-Policy without inline styles. Every label is escaped.
"""

from __future__ import annotations

from dataclasses import dataclass
from html import escape
from typing import Mapping, Sequence

# Distinguishable on screen and for the common colour-vision deficiencies (Okabe-Ito, then Tol's muted).
PALETTE = ("#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00", "#F0E442", "#332288", "#88CCEE",
           "#44AA99", "#117733", "#999933", "#DDCC77", "#CC6677", "#882255", "#AA4499")
UNKNOWN = "#d9d9d9"


def colours(labels: Sequence[str]) -> dict[str, str]:
    """One colour per activity, stable for a household (labels in sorted order)."""
    out = {}
    for i, label in enumerate(sorted(set(labels))):
        out[label] = PALETTE[i % len(PALETTE)] if i < len(PALETTE) else f"hsl({(i * 137) % 360}, 45%, 55%)"
    return out


def _clock(minute: int) -> str:
    m = minute % 1440
    return f"{m // 60:02d}:{m % 60:02d}"


def _hour_ticks(x0: float, width: float, start: int, span: int, top: float, bottom: float,
                every: int = 120) -> list[str]:
    parts = []
    first = -(-start // every) * every
    for m in range(first, start + span + 1, every):
        x = x0 + (m - start) / span * width
        parts.append(f'<line x1="{x:.1f}" y1="{top}" x2="{x:.1f}" y2="{bottom}" class="grid"/>')
        parts.append(f'<text x="{x:.1f}" y="{bottom + 14}" class="tick" text-anchor="middle">{_clock(m)}</text>')
    return parts


def _runs(values: Sequence[str | None]) -> list[tuple[int, int, str | None]]:
    """(start, length, value) of each run of equal values."""
    out: list[tuple[int, int, str | None]] = []
    for i, v in enumerate(values):
        if out and out[-1][2] == v and out[-1][0] + out[-1][1] == i:
            out[-1] = (out[-1][0], out[-1][1] + 1, v)
        else:
            out.append((i, 1, v))
    return out


@dataclass(frozen=True, slots=True)
class TimelineStep:
    minute: int  # since the day's midnight
    observed: str | None
    predicted: str | None
    probability: float | None
    recognised: str | None = None  # read from the home's sensors (a household with sensors)
    recognised_probability: float | None = None


@dataclass(frozen=True, slots=True)
class Layout:
    """A chart's horizontal layout: the plot's width and left margin (user units, drawn 1:1 at
    their size in CSS pixels) and the hours between ticks. :data:`WIDE` for a desktop,
    :data:`NARROW` for a phone (the page shows one of the two by its width)."""

    width: float
    x0: float
    tick_minutes: int


WIDE, NARROW = Layout(900.0, 78.0, 120), Layout(270.0, 70.0, 360)


def day_span(steps_per_day: int, step_minutes: int) -> int:
    """The minutes a chart of the day spans: the household's day (whole hours), at most 24 h,
    so a day of 18 hours leaves no empty quarter."""
    return min(1440, -(-steps_per_day * step_minutes // 60) * 60)


def timeline(steps: Sequence[TimelineStep], *, day_start: int, step_minutes: int, span: int,
             colour: Mapping[str, str], now: int | None = None, layout: Layout = WIDE) -> str:
    """Today: the observed activity, the one recognised from the sensors (a lane of its own,
    "sensors", when any step has one) and, beneath them, GLOBE's prediction for each step made before it (shaded by
    its probability), over the household's day; ``now`` (a minute) marked."""
    width, x0, lane, top = layout.width, layout.x0, 26.0, 18.0
    recognising = any(s.recognised is not None for s in steps)
    names = ("observed", "sensors", "predicted") if recognising else ("observed", "predicted")
    y = {name: top + i * (lane + 8) for i, name in enumerate(names)}
    bottom = top + len(names) * (lane + 8)
    what = "observed, recognised and predicted" if recognising else "observed and predicted"
    parts = [f'<svg viewBox="0 0 {x0 + width + 16:.0f} {bottom + 22:.0f}" '
             f'class="chart" role="img" aria-label="today: {what} activity per step">']
    for name in names:
        parts.append(f'<text x="{x0 - 6}" y="{y[name] + lane / 2 + 4}" class="lane" text-anchor="end">{name}</text>')
        parts.append(f'<rect x="{x0}" y="{y[name]}" width="{width}" height="{lane}" class="lane-bg"/>')
    w = width * step_minutes / span
    for s in steps:
        x = x0 + (s.minute - day_start) % 1440 / span * width
        when = _clock(s.minute)
        if s.observed is not None:
            parts.append(f'<rect x="{x:.1f}" y="{y["observed"]}" width="{w:.2f}" height="{lane}" '
                         f'fill="{colour.get(s.observed, UNKNOWN)}">'
                         f'<title>{when} observed {escape(s.observed)}</title></rect>')
        for lane_name, said, p, verb in (("sensors", s.recognised, s.recognised_probability, "recognised"),
                                         ("predicted", s.predicted, s.probability, "predicted")):
            if said is None or p is None or lane_name not in y:
                continue
            miss = s.observed is not None and s.observed != said
            mark = ' class="miss"' if miss else ""
            parts.append(f'<rect x="{x:.1f}" y="{y[lane_name]}" width="{w:.2f}" height="{lane}" '
                         f'fill="{colour.get(said, UNKNOWN)}" fill-opacity="{0.25 + 0.75 * p:.2f}"'
                         f'{mark}><title>{when} {verb} {escape(said)} '
                         f'(p = {p:.2f}){" - missed" if miss else ""}</title></rect>')
    parts += _hour_ticks(x0, width, day_start, span, top - 4, bottom, layout.tick_minutes)
    if now is not None:
        x = x0 + min((now - day_start) % 1440, span) / span * width
        parts.append(f'<g class="now"><line x1="{x:.1f}" y1="{top - 4}" x2="{x:.1f}" y2="{bottom - 8}"/>'
                     f'<text x="{x:.1f}" y="{top - 7}" text-anchor="middle">now {_clock(now)}</text></g>')
    parts.append("</svg>")
    return "".join(parts)


def actogram(rows: Sequence[tuple[str, Sequence[str | None]]], *, day_start: int, step_minutes: int, span: int,
             colour: Mapping[str, str], layout: Layout = WIDE) -> str:
    """The routine at a glance: one row per day (most recent at the top), time of day across the
    household's day, coloured by activity (runs of one activity drawn as one bar)."""
    width, x0, h = layout.width, layout.x0, 13.0
    top = 4.0
    parts = [f'<svg viewBox="0 0 {x0 + width + 16:.0f} {top + h * len(rows) + 24:.0f}" '
             'class="chart" role="img" aria-label="actogram: activity by day and time of day">']
    w = width * step_minutes / span
    for r, (label, values) in enumerate(rows):
        y = top + r * h
        parts.append(f'<text x="{x0 - 6}" y="{y + h - 3}" class="tick" text-anchor="end">{escape(label)}</text>')
        for start, length, value in _runs(values[:span // step_minutes]):
            if value is None:
                continue
            x = x0 + start * w
            when = _clock(day_start + start * step_minutes)
            parts.append(f'<rect x="{x:.1f}" y="{y:.1f}" width="{length * w:.2f}" height="{h - 1}" '
                         f'fill="{colour.get(value, UNKNOWN)}"><title>{escape(label)} {when}'
                         f' {escape(value)}</title></rect>')
    parts += _hour_ticks(x0, width, day_start, span, top, top + h * len(rows) + 4, layout.tick_minutes)
    parts.append("</svg>")
    return "".join(parts)


def score_chart(days: Sequence[tuple[str, float | None, float | None, float | None]], layout: Layout = WIDE) -> str:
    """Per day (oldest left): activity accuracy, fetch precision and recall, 0 to 1."""
    width, height, x0, y0 = layout.width + layout.x0 - 40.0, 160.0, 40.0, 8.0
    n = max(len(days), 1)
    parts = [f'<svg viewBox="0 0 {x0 + width + 10:.0f} {y0 + height + 26:.0f}" '
             'class="chart" role="img" aria-label="online scores per day">']
    for v in (0.0, 0.5, 1.0):
        y = y0 + (1 - v) * height
        parts.append(f'<line x1="{x0}" y1="{y:.1f}" x2="{x0 + width}" y2="{y:.1f}" class="grid"/>')
        parts.append(f'<text x="{x0 - 6}" y="{y + 4:.1f}" class="tick" text-anchor="end">{v:.1f}</text>')

    def x(i: int) -> float:
        return x0 + (i + 0.5) * width / n

    for k, name in ((1, "accuracy"), (2, "precision"), (3, "recall")):
        points = [(x(i), y0 + (1 - d[k]) * height, d[0], d[k])  # type: ignore[operator]
                  for i, d in enumerate(days) if d[k] is not None]
        if len(points) > 1:
            line = " ".join(f"{px:.1f},{py:.1f}" for px, py, _, _ in points)
            parts.append(f'<polyline class="score {name}" points="{line}"/>')
        for px, py, day, value in points:
            parts.append(f'<circle class="score {name}" cx="{px:.1f}" cy="{py:.1f}" r="3"><title>{escape(day)} {name} '
                         f'{value:.2f}</title></circle>')
    step = max(1, n // round(width / 120))
    for i in range(0, len(days), step):
        parts.append(f'<text x="{x(i):.1f}" y="{y0 + height + 18}" class="tick" text-anchor="middle">'
                     f'{escape(days[i][0][5:])}</text>')
    parts.append("</svg>")
    return "".join(parts)


def step_bars(probabilities: Sequence[float], colour: str = "#0072B2") -> str:
    """A small strip: one cell per coming step, shaded by P(first used then)."""
    w, h = 18, 16
    peak = max(max(probabilities, default=0.0), 1e-9)
    parts = [f'<svg viewBox="0 0 {w * len(probabilities)} {h}" class="bars" '
             'role="img" aria-label="probability per coming step">']
    for i, p in enumerate(probabilities):
        parts.append(f'<rect x="{i * w}" y="0" width="{w - 2}" height="{h}" fill="{colour}" '
                     f'fill-opacity="{0.08 + 0.92 * p / peak:.2f}"><title>+{i + 1} step(s): p = {p:.2f}</title></rect>')
    parts.append("</svg>")
    return "".join(parts)


__all__ = ["NARROW", "WIDE", "Layout", "TimelineStep", "actogram", "colours", "day_span", "score_chart", "step_bars",
           "timeline"]
