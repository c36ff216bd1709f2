"""The certificate's vector charts (reportlab graphics) and its embedded font.

A chart is values with their expanded-uncertainty band against frequency in Hz on a log axis;
the y unit is the caller's (deviation in %, phase in degrees).
"""

from __future__ import annotations

import math
from importlib import resources

from reportlab.graphics.shapes import Drawing, Group, Line, Polygon, PolyLine, Rect, String
from reportlab.lib import colors
from reportlab.lib.styles import ParagraphStyle, getSampleStyleSheet
from reportlab.lib.units import mm
from reportlab.pdfbase import pdfmetrics
from reportlab.pdfbase.ttfonts import TTFont

# DejaVu Sans (app/data, with its license): Latin Extended-A and more, embedded so that names
# such as "Łukasz Żółć" print the same on every machine (the PDF base fonts have no glyphs).
FONT, FONT_BOLD = "DejaVuSans", "DejaVuSans-Bold"


def _register_fonts() -> None:
    """Register the packaged DejaVu Sans (regular, bold) with reportlab, once."""
    if FONT in pdfmetrics.getRegisteredFontNames():
        return
    data = resources.files("app").joinpath("data")
    for name, file in ((FONT, "DejaVuSans.ttf"), (FONT_BOLD, "DejaVuSans-Bold.ttf")):
        with resources.as_file(data.joinpath(file)) as path:
            pdfmetrics.registerFont(TTFont(name, str(path)))
    pdfmetrics.registerFontFamily(
        FONT, normal=FONT, bold=FONT_BOLD, italic=FONT, boldItalic=FONT_BOLD
    )


_register_fonts()
GRID = colors.Color(0.75, 0.75, 0.75)

# the certificate's paragraph styles (the PDF and its sections: pdf, triaxial_pdf)
STYLES = getSampleStyleSheet()
BODY = ParagraphStyle("body", parent=STYLES["BodyText"], fontName=FONT, fontSize=9, leading=11.5)
SMALL = ParagraphStyle("small", parent=BODY, fontSize=7.5, leading=9.5)
HEAD = ParagraphStyle(
    "head",
    parent=STYLES["Heading2"],
    fontName=FONT_BOLD,
    fontSize=11.5,
    spaceBefore=8,
    spaceAfter=3,
)
HEAD_KEEP = ParagraphStyle("head_keep", parent=HEAD, keepWithNext=1)
BAND = colors.Color(0.78, 0.86, 0.97)
INK = colors.Color(0.1, 0.25, 0.55)


def _nice_ticks(low: float, high: float, count: int = 5) -> list[float]:
    span = max(high - low, 1e-12)
    raw = span / count
    magnitude = 10 ** math.floor(math.log10(raw))
    step = min((m * magnitude for m in (1, 2, 2.5, 5, 10) if m * magnitude >= raw), default=raw)
    start = math.floor(low / step) * step
    stop = math.ceil(high / step) * step  # the ticks enclose [low, high]
    count = round((stop - start) / step)
    return [round(start + i * step, 10) for i in range(count + 1)]


def chart(
    frequencies: list[float],
    values: list[float],
    half_widths: list[float],
    y_label: str,
    width: float = 170 * mm,
    height: float = 58 * mm,
) -> Drawing:
    """Vector chart on a log frequency axis: the values and their uncertainty band."""
    left, bottom, right, top = 16 * mm, 10 * mm, 4 * mm, 4 * mm
    d = Drawing(width, height, initialFontName=FONT)  # the renderer's state starts in it
    pw, ph = width - left - right, height - bottom - top
    f_lo, f_hi = min(frequencies) / 1.25, max(frequencies) * 1.25
    lower = [v - u for v, u in zip(values, half_widths, strict=True)]
    upper = [v + u for v, u in zip(values, half_widths, strict=True)]
    finite = [x for x in lower + upper if math.isfinite(x)] or [-1.0, 1.0]
    ticks = _nice_ticks(min(finite), max(finite))
    y_lo, y_hi = ticks[0], ticks[-1] if ticks[-1] > ticks[0] else ticks[0] + 1

    def x(f: float) -> float:
        return left + pw * (math.log10(f) - math.log10(f_lo)) / (
            math.log10(f_hi) - math.log10(f_lo)
        )

    def y(v: float) -> float:
        return bottom + ph * (v - y_lo) / (y_hi - y_lo)

    d.add(Rect(left, bottom, pw, ph, strokeColor=colors.black, fillColor=None, strokeWidth=0.6))
    for t in ticks:
        d.add(Line(left, y(t), left + pw, y(t), strokeColor=GRID, strokeWidth=0.3))
        d.add(String(left - 2, y(t) - 2.5, f"{t:g}", fontName=FONT, fontSize=6.5, textAnchor="end"))
    decade = 10 ** math.floor(math.log10(f_lo))
    while decade <= f_hi:
        for m in (1, 2, 5):
            f = m * decade
            if f_lo <= f <= f_hi:
                d.add(Line(x(f), bottom, x(f), bottom + ph, strokeColor=GRID, strokeWidth=0.3))
                d.add(
                    String(
                        x(f), bottom - 8, f"{f:g}", fontName=FONT, fontSize=6.5, textAnchor="middle"
                    )
                )
        decade *= 10
    d.add(
        String(
            left + pw / 2,
            1,
            "frequency in Hz (log scale)",
            fontName=FONT,
            fontSize=7,
            textAnchor="middle",
        )
    )
    label = Group(String(0, 0, y_label, fontName=FONT, fontSize=7, textAnchor="middle"))
    label.transform = (0, 1, -1, 0, 5, bottom + ph / 2)  # rotated 90 degrees
    d.add(label)
    band = [(x(f), y(v)) for f, v in zip(frequencies, upper, strict=True)]
    band += [(x(f), y(v)) for f, v in reversed(list(zip(frequencies, lower, strict=True)))]
    if all(math.isfinite(p[1]) for p in band):
        d.add(Polygon([c for p in band for c in p], fillColor=BAND, strokeColor=None))
    d.add(
        PolyLine(
            [c for f, v in zip(frequencies, values, strict=True) for c in (x(f), y(v))],
            strokeColor=INK,
            strokeWidth=1,
        )
    )
    for f, v in zip(frequencies, values, strict=True):
        d.add(Rect(x(f) - 1.2, y(v) - 1.2, 2.4, 2.4, fillColor=INK, strokeColor=None))
    return d
