"""A sensor's history chart as an SVG drawn on the server: sensitivity at the reference
frequency in mV/(m/s^2) against calibration date, each point with its expanded uncertainty
bar (k = 2). No JavaScript; text is escaped by ElementTree.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from datetime import UTC, datetime

from app.records.db.lab import History

WIDTH, HEIGHT = 720, 360
LEFT, RIGHT, TOP, BOTTOM = 80, 40, 30, 50  # margins in px
SVG_NS = "http://www.w3.org/2000/svg"


def nice_ticks(low: float, high: float, count: int = 5) -> list[float]:
    """About `count` round tick values (1, 2 or 5 times a power of ten) spanning low..high."""
    if not (math.isfinite(low) and math.isfinite(high)) or high <= low:
        return [low]
    raw = (high - low) / count
    power = 10 ** math.floor(math.log10(raw))
    step = next(m * power for m in (1, 2, 5, 10) if m * power >= raw)
    first = math.ceil(low / step) * step
    ticks = []
    value = first
    while value <= high + step * 1e-9:
        ticks.append(round(value, 12))
        value += step
    return ticks


def history_svg(history: History) -> str:
    """The SVG document of `history` (an explanatory text when it has no points)."""
    svg = ET.Element(
        "svg",
        xmlns=SVG_NS,
        width=str(WIDTH),
        height=str(HEIGHT),
        viewBox=f"0 0 {WIDTH} {HEIGHT}",
        role="img",
    )
    title = f"{history.serial}: sensitivity at the reference frequency"
    if history.drift_percent_per_year is not None:
        title += f" (drift {history.drift_percent_per_year:+.3f} % per year)"
    ET.SubElement(svg, "title").text = title
    _text(svg, WIDTH / 2, 18, title, anchor="middle", size=13)
    points = history.points
    if not points:
        _text(svg, WIDTH / 2, HEIGHT / 2, "no calibrations on record", anchor="middle")
        return ET.tostring(svg, encoding="unicode")
    times = [p.started_utc.timestamp() for p in points]
    values = [p.sensitivity_mv_per_ms2 for p in points]
    halves = [p.expanded_uncertainty_mv_per_ms2 or 0.0 for p in points]
    span = max(times) - min(times) or 2 * 86400.0
    t0, t1 = min(times) - 0.05 * span, max(times) + 0.05 * span  # no point on the frame
    v0 = min(v - u for v, u in zip(values, halves, strict=True))
    v1 = max(v + u for v, u in zip(values, halves, strict=True))
    pad = (v1 - v0) * 0.1 or abs(v1) * 0.01 or 1.0
    v0, v1 = v0 - pad, v1 + pad
    plot_w, plot_h = WIDTH - LEFT - RIGHT, HEIGHT - TOP - BOTTOM

    def x(t: float) -> float:
        return LEFT + (t - t0) / (t1 - t0) * plot_w

    def y(v: float) -> float:
        return TOP + (v1 - v) / (v1 - v0) * plot_h

    ET.SubElement(
        svg, "rect", x=str(LEFT), y=str(TOP), width=str(plot_w), height=str(plot_h),
        fill="none", stroke="black",
    )  # fmt: skip
    for tick in nice_ticks(v0, v1):
        ET.SubElement(
            svg, "line", x1=str(LEFT - 4), x2=str(LEFT + plot_w), y1=f"{y(tick):.1f}",
            y2=f"{y(tick):.1f}", stroke="#ddd",
        )  # fmt: skip
        _text(svg, LEFT - 6, y(tick) + 4, f"{tick:.6g}", anchor="end")
    _text(svg, 14, TOP + plot_h / 2, "sensitivity in mV/(m/s²)", anchor="middle", rotate=True)
    labelled = times if len(times) <= 6 else [times[0], times[len(times) // 2], times[-1]]
    shown: set[str] = set()
    for t in labelled:
        label = datetime.fromtimestamp(t, UTC).strftime("%Y-%m-%d")
        if label not in shown:  # one label per day
            shown.add(label)
            _text(svg, x(t), TOP + plot_h + 18, label, anchor="middle")
    _text(svg, LEFT + plot_w / 2, HEIGHT - 8, "calibration date (UTC)", anchor="middle")
    line = " ".join(f"{x(t):.1f},{y(v):.1f}" for t, v in zip(times, values, strict=True))
    ET.SubElement(svg, "polyline", points=line, fill="none", stroke="#1f4e9c")
    for point, t, v, u in zip(points, times, values, halves, strict=True):
        ET.SubElement(
            svg, "line", x1=f"{x(t):.1f}", x2=f"{x(t):.1f}", y1=f"{y(v - u):.1f}",
            y2=f"{y(v + u):.1f}", stroke="black",
        )  # fmt: skip
        dot = ET.SubElement(svg, "circle", cx=f"{x(t):.1f}", cy=f"{y(v):.1f}", r="4")
        dot.set("fill", "#1f4e9c")
        dot.set("class", "point")
        ET.SubElement(
            dot, "title"
        ).text = (
            f"{point.run_id}: {v:.6g} ± {u:.2g} mV/(m/s²) at {point.reference_frequency_hz:g} Hz"
        )
    return ET.tostring(svg, encoding="unicode")


def _text(
    parent: ET.Element,
    x: float,
    y: float,
    content: str,
    *,
    anchor: str = "start",
    size: int = 11,
    rotate: bool = False,
) -> None:
    element = ET.SubElement(parent, "text", x=f"{x:.1f}", y=f"{y:.1f}")
    element.set("text-anchor", anchor)
    element.set("font-size", str(size))
    element.set("font-family", "sans-serif")
    if rotate:
        element.set("transform", f"rotate(-90 {x:.1f} {y:.1f})")
    element.text = content
