"""The certificate's marked text layer: each printed item the certificate states (number,
customer, serial, dates, run, seal, records chain head, verdict, every cell of the results
table) is drawn inside a PDF marked-content sequence that names it, and `accelcal verify` reads
the page back through those marks only.

The delimiters are content-stream operators the writer places around the item's text,

    /Span << /AcItem (seal) >> BDC  ...the drawn text...  EMC
    /Span << /AcItem (s) /AcLine 3 >> BDC  ...  EMC          (a cell: its column and line)

never characters of the text, so no label, customer name or note can open, close or forge an
item: whatever it contains is text inside a string operand. The reader is strict: an unknown
item, an item inside another, an item or a cell printed twice, or an unclosed item is refused
(MarkError). The text of an item is what its glyphs say (pypdf, through the fonts' ToUnicode
maps), one string per printed line; `printed_equal` compares it with a stated value, a line
break standing for one blank or for nothing (a name wraps at its blanks, a hash inside).
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from reportlab.platypus import Paragraph, Table

from app.certificate.printed import Column, Item
from app.errors import Refusal

MARK_TAG = "/Span"
ITEM_KEY = "/AcItem"
LINE_KEY = "/AcLine"
MAX_LINES = 10_000  # a results table of this program has at most some hundred lines


class PrintedText(str):
    """An item as a page prints it: its lines joined by '\n' (compare with `printed_equal`)."""


class MarkError(Refusal):
    """A certificate whose marked text layer cannot be read unambiguously; says why."""


def _begin(item: str, line: int | None = None) -> str:
    """The operator that opens a marked item (names from Item/Column only: no escaping)."""
    extra = f" {LINE_KEY} {line:d}" if line is not None else ""
    return f"{MARK_TAG} <<{ITEM_KEY} ({item}){extra}>> BDC"


class MarkedText(str):
    """A table cell's string drawn inside its mark (a results table cell: column and line)."""

    mark: str
    line: int | None

    def __new__(cls, text: str, mark: str, line: int | None = None) -> MarkedText:
        made = super().__new__(cls, text)
        made.mark, made.line = mark, line
        return made


class MarkedParagraph(Paragraph):
    """A paragraph drawn inside the mark of `item` (never split: a table cell or a short
    block)."""

    def __init__(self, text: str, style: Any, item: Item):
        super().__init__(text, style)
        self.mark = item

    def draw(self) -> None:
        self.canv.addLiteral(_begin(self.mark))
        super().draw()
        self.canv.addLiteral("EMC")


class MarkedTable(Table):
    """A table whose MarkedText cells are drawn inside their marks (reportlab draws each
    cell's string as its own text object)."""

    def _drawCell(self, cellval: Any, cellstyle: Any, pos: Any, size: Any) -> None:
        if not isinstance(cellval, MarkedText):
            super()._drawCell(cellval, cellstyle, pos, size)
            return
        self.canv.addLiteral(_begin(cellval.mark, cellval.line))
        super()._drawCell(cellval, cellstyle, pos, size)
        self.canv.addLiteral("EMC")


# --- reading ----------------------------------------------------------------------------------


@dataclass
class PageMarks:
    """What the marked layer of a PDF says: each item's printed lines, each cell's (line,
    column) lines, and the page (0-based) each table line is printed on."""

    items: dict[Item, tuple[str, ...]] = field(default_factory=dict)
    cells: dict[tuple[int, Column], tuple[str, ...]] = field(default_factory=dict)
    line_pages: dict[int, int] = field(default_factory=dict)

    def item(self, name: Item) -> PrintedText:
        """The item as printed, its lines joined by '\\n' ('' when not printed)."""
        return PrintedText("\n".join(self.items.get(name, ())))

    def cell(self, line: int, column: Column) -> PrintedText | None:
        """The cell of `line` (1-based) in `column` as printed; None when not printed."""
        found = self.cells.get((line, column))
        return None if found is None else PrintedText("\n".join(found))

    @property
    def lines(self) -> int:
        """How many table lines are printed (1..lines, each with at least one cell)."""
        return max(self.line_pages, default=0)


class _Reader:
    """Collects the text pypdf extracts between our BDC and its EMC, on one page."""

    def __init__(self, marks: PageMarks, page: int):
        self.marks, self.page = marks, page
        self.depth = 0  # marked-content nesting, ours or not
        self.open: tuple[str, int | None, int] | None = None  # name, line, depth it opened at
        self.text: list[str] = []

    def operator(self, op: bytes, args: Sequence[Any], cm: Any, tm: Any) -> None:
        if op in (b"BDC", b"BMC"):
            self.depth += 1
            mark = _mark_of(args) if op == b"BDC" else None
            if mark is not None:
                if self.open is not None:
                    raise MarkError(f"page {self.page + 1}: item {mark[0]} inside {self.open[0]}")
                self.open, self.text = (mark[0], mark[1], self.depth), []
        elif op == b"EMC":
            if self.open is not None and self.open[2] == self.depth:
                self._close()
            self.depth -= 1
            if self.depth < 0:
                raise MarkError(f"page {self.page + 1}: EMC without its BDC")

    def text_shown(self, text: str, *_: Any) -> None:
        if self.open is not None:
            self.text.append(text)

    def _close(self) -> None:
        assert self.open is not None
        name, line, _ = self.open
        self.open = None
        lines = tuple(s.strip() for s in "".join(self.text).splitlines() if s.strip())
        if line is None:
            item = Item(name)
            if item in self.marks.items:
                raise MarkError(f"{item}: printed twice")
            self.marks.items[item] = lines
            return
        key = (line, Column(name))
        if key in self.marks.cells:
            raise MarkError(f"line {line} {name}: printed twice")
        self.marks.cells[key] = lines
        self.marks.line_pages.setdefault(line, self.page)

    def finish(self) -> None:
        if self.open is not None:
            raise MarkError(f"page {self.page + 1}: item {self.open[0]} is never closed")


def _mark_of(args: Sequence[Any]) -> tuple[str, int | None] | None:
    """(item or column name, table line) of our mark's BDC operands; None for another's."""
    if len(args) != 2 or str(args[0]) != MARK_TAG or not hasattr(args[1], "get"):
        return None
    raw = args[1].get(ITEM_KEY)
    if raw is None:
        return None
    name = bytes(raw).decode("ascii", "replace") if isinstance(raw, bytes) else str(raw)
    line = args[1].get(LINE_KEY)
    if line is None:
        if name not in Item.__members__.values():
            raise MarkError(f"unknown printed item {name!r}")
        return name, None
    if name not in Column.__members__.values():
        raise MarkError(f"unknown column {name!r}")
    if not isinstance(line, int) or isinstance(line, bool) or not 1 <= line <= MAX_LINES:
        raise MarkError(f"column {name}: line {line!r} is not a line number")
    return name, int(line)


def read_marks(data: bytes) -> PageMarks:
    """The marked text layer of the PDF `data` (every page); MarkError when it is ambiguous,
    ValueError and pypdf's own errors when the file cannot be read."""
    from pypdf import PdfReader

    marks = PageMarks()
    for number, page in enumerate(PdfReader(io.BytesIO(data)).pages):
        reader = _Reader(marks, number)
        page.extract_text(visitor_operand_before=reader.operator, visitor_text=reader.text_shown)
        reader.finish()
    lines = sorted(marks.line_pages)
    if lines != list(range(1, len(lines) + 1)):
        raise MarkError(f"the table's lines are not 1..{len(lines)}: {lines[:5]}...")
    return marks


def printed_equal(printed: str, stated: str) -> bool:
    """Whether `printed` (lines joined by '\\n', as PageMarks.item gives them) prints `stated`:
    the same text with blanks collapsed (a paragraph sets them so), each line break standing
    for one blank or for nothing (where a long word was broken)."""
    words = " ".join(stated.split())
    position = 0
    lines = printed.split("\n")
    for index, line in enumerate(lines):
        if not words.startswith(line, position):
            return False
        position += len(line)
        if index < len(lines) - 1 and words.startswith(" ", position):
            position += 1
    return position == len(words)
