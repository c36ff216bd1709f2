"""What a certificate prints, as typed values, read back from its DCC, its PDF's marked text
layer (app.certificate.pdf_marks) or its run, so that `verify` compares them value by value
(never by searching one text in another, never by a label's place).

Every value is the string as printed (rounded once, by app.certificate.printed): a frequency
in Hz, a sensitivity and its expanded uncertainty U in mV/(m/s^2), a phase and its U in
degrees, the coverage factor k, the deviation from the reference-frequency sensitivity and its
U in %; "n/s" where a phase is not stated; None where a source never prints an item (the PDF's
table has no U of the deviation), which is then not compared.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, fields
from typing import Any

from lxml import etree

from app.certificate.dcc import (
    CHAIN_HEAD_NAME,
    DCC_NS,
    DEVIATION_NAME,
    RUN_ID_NAME,
    SEAL_NAME,
    SI_NS,
)
from app.certificate.pdf_marks import PageMarks, PrintedText, printed_equal
from app.certificate.printed import Column, Item, PrintedLine
from app.errors import Refusal

NOT_STATED = "n/s"
MAX_DCC_BYTES = 4 << 20  # a DCC of this program is some 10 kB


class PrintedError(Refusal):
    """A DCC that cannot be read safely (too large, a DTD or entity, not well-formed)."""


@dataclass(frozen=True)
class PrintedRow:
    """One line of the results table as read back: frequency, sensitivity, its U, phase, its
    U, k, deviation, its U (None: this source does not print it)."""

    f: str
    s: str
    u: str
    ph: str
    u_ph: str
    k: str
    dev: str | None
    u_dev: str | None


@dataclass(frozen=True)
class PrintedItems:
    """The items a certificate states ("" where one is not found) and its lines."""

    number: str = ""
    customer: str = ""
    serial: str = ""
    calibration_date: str = ""
    issue_date: str = ""
    run_id: str = ""
    seal: str = ""
    chain_head: str = ""
    verdict: str = ""
    replaces: str = ""  # an amendment: the number it replaces ("" for a first issue)
    amendment_reason: str = ""
    lines: tuple[PrintedRow, ...] = ()


def differences(a: PrintedItems, b: PrintedItems, a_name: str, b_name: str) -> list[str]:
    """Each item where `a` and `b` differ, one short line each, naming the item and line."""
    out = []
    for item in fields(PrintedItems):
        if item.name == "lines":
            continue
        x, y = getattr(a, item.name), getattr(b, item.name)
        if not _same(x, y):
            out.append(f"{item.name}: {a_name} {x!r}, {b_name} {y!r}")
    if len(a.lines) != len(b.lines):
        out.append(f"lines: {a_name} has {len(a.lines)}, {b_name} {len(b.lines)}")
    for i, (x, y) in enumerate(zip(a.lines, b.lines, strict=False), start=1):
        for item in fields(PrintedRow):
            xv, yv = getattr(x, item.name), getattr(y, item.name)
            if xv is not None and yv is not None and not _same(xv, yv):
                out.append(
                    f"line {i} {item.name}: {a_name} {getattr(x, item.name)!r}, "
                    f"{b_name} {getattr(y, item.name)!r}"
                )
    return out


def _same(x: str, y: str) -> bool:
    """Equal; or, when one is read from a page (PrintedText), the other printed by it
    (app.certificate.pdf_marks.printed_equal: a line break is one blank or none)."""
    if isinstance(x, PrintedText) and not isinstance(y, PrintedText):
        return printed_equal(x, y)
    if isinstance(y, PrintedText) and not isinstance(x, PrintedText):
        return printed_equal(y, x)
    return x == y


def rows_of(lines: tuple[PrintedLine, ...], phase_stated: bool) -> tuple[PrintedRow, ...]:
    """The rows a run's results print (app.certificate.printed; phase "n/s" when not stated)."""
    return tuple(
        PrintedRow(
            ln.frequency,
            ln.sensitivity,
            ln.expanded,
            ln.phase if phase_stated else NOT_STATED,
            ln.phase_expanded if phase_stated else NOT_STATED,
            ln.k,
            ln.deviation,
            ln.deviation_expanded,
        )
        for ln in lines
    )


# --- the DCC ----------------------------------------------------------------------------------


def parse_inert(xml: bytes) -> Any:
    """The root element of `xml` parsed as bytes by a parser that resolves nothing: no DTD
    loaded, no entity expanded, no network, no file named by the document opened. A DOCTYPE
    is refused. PrintedError says why."""
    if len(xml) > MAX_DCC_BYTES:
        raise PrintedError(f"{len(xml)} bytes, more than a DCC may hold ({MAX_DCC_BYTES})")
    parser = etree.XMLParser(
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        dtd_validation=False,
        huge_tree=False,
        remove_pis=True,
    )
    try:
        root = etree.fromstring(xml, parser=parser)
    except etree.XMLSyntaxError as exc:
        raise PrintedError(f"not well-formed XML ({exc})") from None
    tree = root.getroottree()
    if tree.docinfo.doctype or tree.docinfo.internalDTD is not None:
        raise PrintedError("it has a DOCTYPE (a DCC has none; entities are never expanded)")
    if any(isinstance(node, etree._Entity) for node in root.iter()):
        raise PrintedError("it has entity references (a DCC has none)")
    return root


def _ns() -> dict[str, str]:
    return {"dcc": DCC_NS, "si": SI_NS}


def _text(root: Any, path: str) -> str:
    found = root.xpath(path, namespaces=_ns())
    if not found:
        return ""
    node = found[0]
    return str(node if isinstance(node, str) else (node.text or "")).strip()


def _identification(parent: str, name: str) -> str:
    return (
        f"{parent}/dcc:identifications/dcc:identification[dcc:name/dcc:content='{name}']/dcc:value"
    )


def items_from_dcc(root: Any) -> PrintedItems:
    """The printed items of a DCC (parsed by `parse_inert`)."""
    admin = "/dcc:digitalCalibrationCertificate/dcc:administrativeData"
    core = f"{admin}/dcc:coreData"
    customer = _text(root, f"{admin}/dcc:customer/dcc:name/dcc:content")
    address = _text(root, f"{admin}/dcc:customer/dcc:location/dcc:further/dcc:content")
    declaration = _text(root, f"{admin}/dcc:statements/dcc:statement/dcc:declaration/dcc:content")
    verdict = re.match(r"Overall verdict: (.*?)\. Decision rule", declaration)
    lists: dict[str, tuple[list[str], list[str], list[str]]] = {}
    for quantity in root.xpath(
        "/dcc:digitalCalibrationCertificate/dcc:measurementResults/dcc:measurementResult"
        "/dcc:results/dcc:result/dcc:data/dcc:list/dcc:quantity",
        namespaces=_ns(),
    ):
        name = _text(quantity, "dcc:name/dcc:content")
        real = "si:realListXMLList"
        lists[name] = (
            _text(quantity, f"{real}/si:valueXMLList").split(),
            _text(quantity, f"{real}//si:valueExpandedMUXMLList").split(),
            _text(quantity, f"{real}//si:coverageFactorXMLList").split(),
        )
    f = lists.get("Excitation frequency", ([], [], []))[0]
    s, u, k = lists.get("Sensitivity magnitude", ([], [], []))
    dev, u_dev = lists.get(DEVIATION_NAME, ([], [], []))[:2]
    phase = next((v for n, v in lists.items() if n.startswith("Phase shift")), None)
    ph, u_ph = (phase[0], phase[1]) if phase else ([NOT_STATED] * len(f), [NOT_STATED] * len(f))
    count = len(f)
    if any(len(column) != count for column in (s, u, k, ph, u_ph, dev, u_dev)):
        count = -1  # lists of different lengths (or no deviation list): no line can be trusted
    lines = tuple(
        PrintedRow(f[i], s[i], u[i], ph[i], u_ph[i], k[i], dev[i], u_dev[i])
        for i in range(max(count, 0))
    )
    return PrintedItems(
        number=_text(root, f"{core}/dcc:uniqueIdentifier"),
        customer=customer if address in ("", customer) else f"{customer}, {address}",
        serial=_text(root, _identification(f"{admin}/dcc:items/dcc:item", "Serial number")),
        calibration_date=_text(root, f"{core}/dcc:beginPerformanceDate"),
        issue_date=_text(root, f"{core}/dcc:issueDate"),
        run_id=_text(root, _identification(core, RUN_ID_NAME)),
        seal=_text(root, _identification(core, SEAL_NAME)),
        chain_head=_text(root, _identification(core, CHAIN_HEAD_NAME)),
        verdict=verdict.group(1) if verdict else "",
        replaces=_replaced(root, core),
        amendment_reason=_text(root, f"{core}/dcc:previousReport/dcc:description/dcc:content"),
        lines=lines if count >= 0 else (PrintedRow("", "", "", "", "", "", "", ""),),
    )


def _replaced(root: Any, core: str) -> str:
    """The number an amendment's DCC replaces: previousReport's referralID, which must equal
    reportAmendedSubstituted's replacedUniqueIdentifier (both, or neither, present); when they
    disagree both are returned, so that no comparison can hold."""
    named = _text(root, f"{core}/dcc:previousReport/dcc:referralID")
    substituted = _text(root, f"{core}/dcc:reportAmendedSubstituted/dcc:replacedUniqueIdentifier")
    return named if named == substituted else f"{named} | {substituted}"


# --- the PDF's marked text layer -------------------------------------------------------------


def items_from_pdf(marks: PageMarks) -> PrintedItems:
    """The printed items of a certificate as its marked text layer states them
    (app.certificate.pdf_marks.read_marks): a wrapped item keeps its line breaks ('\n', see
    `differences`), a table line its cells (the deviation's U included, as in the DCC)."""
    items = {item.value: marks.item(item) for item in Item}

    def cell(line: int, column: Column) -> str:
        return marks.cell(line, column) or ""

    lines = tuple(
        PrintedRow(
            f=cell(n, Column.FREQUENCY),
            s=cell(n, Column.SENSITIVITY),
            u=cell(n, Column.EXPANDED),
            ph=cell(n, Column.PHASE),
            u_ph=cell(n, Column.PHASE_EXPANDED),
            k=cell(n, Column.K),
            dev=cell(n, Column.DEVIATION),
            u_dev=cell(n, Column.DEVIATION_EXPANDED),
        )
        for n in range(1, marks.lines + 1)
    )
    return PrintedItems(**items, lines=lines)
