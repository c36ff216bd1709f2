"""The certificate's page furniture: the running header (laboratory, certificate number), the
footer with 'page x of y', and the document's creation date; lengths in points (reportlab).

The laboratory's name is never cut: it is set smaller, down to MIN_HEADER_PT, and then on two
lines. The PDF's creation date is the real moment of writing (UTC), or $SOURCE_DATE_EPOCH
(s since 1970, the reproducible-builds convention) when set; reportlab's invariant mode keeps
every other byte the same for the same run and items.
"""

from __future__ import annotations

import os
import time
from typing import Any

from reportlab.lib.pagesizes import A4
from reportlab.lib.units import mm
from reportlab.pdfbase import pdfmetrics
from reportlab.pdfgen import canvas as pdf_canvas

import app.certificate.text as text
from app.certificate.pdf_charts import FONT, FONT_BOLD, GRID

HEADER_PT = 8.5  # the running header's size, pt
MIN_HEADER_PT = 6.5  # the smallest the laboratory's name is set before it wraps, pt
MARGIN = 18 * mm


class CreationStamp:
    """What reportlab's PDFDate reads (YMDhms, UTC offset dhh:dmm): the creation moment, UTC."""

    def __init__(self) -> None:
        epoch = os.environ.get("SOURCE_DATE_EPOCH", "").strip()
        try:
            self.t = float(int(epoch)) if epoch else time.time()
        except ValueError:
            self.t = time.time()
        self.YMDhms = tuple(time.gmtime(self.t))[:6]
        self.dhh = self.dmm = 0
        self.tzname = "UTC"


def header_lines(name: str, room: float) -> tuple[float, list[str]]:
    """The laboratory's name for the header within `room` points: (size in pt, lines); one
    line at the largest size from HEADER_PT down to MIN_HEADER_PT that fits, else two lines
    broken at a blank at MIN_HEADER_PT (a word too long for a line is left as it is)."""
    size = HEADER_PT
    while size >= MIN_HEADER_PT:
        if pdfmetrics.stringWidth(name, FONT_BOLD, size) <= room:
            return size, [name]
        size -= 0.5
    words = name.split()
    first: list[str] = []
    while (
        words
        and pdfmetrics.stringWidth(" ".join([*first, words[0]]), FONT_BOLD, MIN_HEADER_PT) <= room
    ):
        first.append(words.pop(0))
    if not first:
        first.append(words.pop(0))
    return MIN_HEADER_PT, [" ".join(first), " ".join(words)] if words else [" ".join(first)]


def numbered_canvas(number: str, laboratory: str) -> type[pdf_canvas.Canvas]:
    """A canvas class that writes the header and 'page x of y' once all pages are known."""

    class NumberedCanvas(pdf_canvas.Canvas):
        def __init__(self, *args: Any, **kwargs: Any):
            kwargs["invariant"] = True
            kwargs["initialFontName"] = FONT  # else each page's preamble names Helvetica
            super().__init__(*args, **kwargs)
            self._doc._timeStamp = CreationStamp()  # the info dates; the ID stays invariant
            self._pages: list[dict[str, Any]] = []

        def showPage(self) -> None:
            self._pages.append(dict(self.__dict__))
            self._startPage()

        def save(self) -> None:
            total = len(self._pages)
            for page in self._pages:
                self.__dict__.update(page)
                self._furniture(total)
                super().showPage()
            super().save()

        def _furniture(self, total: int) -> None:
            width, height = A4
            right = f"Calibration certificate {number}"
            room = width - 2 * MARGIN - pdfmetrics.stringWidth(right, FONT, HEADER_PT) - 6 * mm
            size, lines = header_lines(laboratory, room)
            top = height - 12 * mm + (size + 0.5) * (len(lines) - 1) / 2
            self.setFont(FONT_BOLD, size)
            for i, line in enumerate(lines):
                self.drawString(MARGIN, top - i * (size + 1), line)
            self.setFont(FONT, HEADER_PT)
            self.drawRightString(width - MARGIN, height - 12 * mm, right)
            self.setStrokeColor(GRID)
            self.line(MARGIN, height - 14 * mm, width - MARGIN, height - 14 * mm)
            self.line(MARGIN, 16 * mm, width - MARGIN, 16 * mm)
            self.setFont(FONT, 7.5)
            self.drawString(MARGIN, 11.5 * mm, text.FOOTER)
            self.drawRightString(
                width - MARGIN,
                7.5 * mm,
                f"Certificate {number}   page {self._pageNumber} of {total}",
            )

    return NumberedCanvas
