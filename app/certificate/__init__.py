"""The PDF calibration certificate (SPEC.md section 10; ISO/IEC 17025 clause 7.8).

Made from a stored, complete run folder only (results.json, config.json), never from live
state. Numbers are the stored results rounded per GUM 7.2.6 (uncertainty to two significant
digits, value to the same decimal place); nothing is recomputed. Items not in the run
(customer, authorising person, conditions) come from options or the stand configuration's
[certificate] table; missing mandatory items are refused by name. The PDF is reproducible:
reportlab's invariant mode and dates taken from the run make the same run and options give the
same bytes. A certificate is issued under the run folder's lock, numbered uniquely under the
runs root (app.records.register) and written atomically, never over a file; the read-only
run folder is opened only for the moment it is written into.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import re
from dataclasses import dataclass, field, fields
from datetime import date
from importlib import resources
from pathlib import Path
from typing import Any

from reportlab.graphics.shapes import Drawing, Group, Line, Polygon, PolyLine, Rect, String
from reportlab.lib import colors
from reportlab.lib.enums import TA_CENTER
from reportlab.lib.pagesizes import A4
from reportlab.lib.styles import ParagraphStyle, getSampleStyleSheet
from reportlab.lib.units import mm
from reportlab.pdfbase import pdfmetrics
from reportlab.pdfbase.ttfonts import TTFont
from reportlab.pdfgen import canvas as pdf_canvas
from reportlab.platypus import (
    KeepTogether,
    Paragraph,
    SimpleDocTemplate,
    Spacer,
    Table,
    TableStyle,
)

from app import formatting as fmt
from app.certificate.dcc import line_values
from app.files import FileExistsRefusal, write_with
from app.io.checks import MAX_TEXT_BYTES, InputFileError, check_input_file
from app.io.vocabulary import RunStatus
from app.procedure.modes import MODE_MULTISINE
from app.records.register import Issued, Register, RegisterError, locked_register
from app.records.run_folder import (
    STATUS_COMPLETE,
    is_product_name,
    is_run_folder,
    load_run,
    sha256_of,
    try_lock,
    unlock,
    writable_folder,
)
from app.records.run_record import DutIdentity, RunRecord
from dsp.calibration import NOT_STATED, Results
from dsp.uncertainty import Budget, Quantity

MANDATORY = (
    ("customer", "--customer"),
    ("authorised_by", "--authorised-by"),
    ("dut_model", "--dut-model"),
    ("dut_serial", "--dut-serial (or --dut-id when running)"),
    ("dut_type", "--dut-type"),
    ("temperature_c", "--temperature"),
    ("mounting", "--mounting"),
)


class CertificateError(ValueError):
    """A certificate that must not be issued; the message says why (missing items by name)."""


@dataclass(frozen=True)
class CertificateInfo:
    """What the certificate needs beyond the run."""

    customer: str | None = None
    customer_address: str = ""
    authorised_by: str | None = None
    dut_model: str | None = None
    dut_serial: str | None = None
    dut_type: str | None = None
    temperature_c: float | None = None
    mounting: str | None = None
    certificate_number: str | None = None
    issue_date: str | None = None
    notes: str = ""

    def merged(self, defaults: dict[str, Any]) -> CertificateInfo:
        """Options win; empty ones take the default."""
        values = {}
        for f in fields(self):
            mine = getattr(self, f.name)
            values[f.name] = mine if mine not in (None, "") else defaults.get(f.name, mine)
        return CertificateInfo(**values)


@dataclass(frozen=True)
class StoredRun:
    """What the certificate reads from a run folder."""

    path: Path
    record: RunRecord
    config: dict[str, Any]
    results: Results
    budget: Budget = field(default_factory=Budget)


def load_stored_run(path: str | Path) -> StoredRun:
    """A complete run, or CertificateError saying why not."""
    path = Path(path)
    try:
        record = load_run(path)
    except ValueError as exc:
        raise CertificateError(str(exc)) from None
    if record.status != STATUS_COMPLETE or not record.results:
        reason = record.abort_reason or "no results"
        raise CertificateError(
            f"{path}: the run is {record.status} ({reason}); no certificate is issued for "
            "an incomplete run"
        )
    config_path = path / "config.json"
    config = json.loads(config_path.read_text(encoding="utf-8")) if config_path.exists() else {}
    budget = Budget.from_list(list(record.budget))
    return StoredRun(path, record, config, Results.from_dict(dict(record.results)), budget)


def default_info(run: StoredRun) -> dict[str, Any]:
    """Defaults from the run and the stand's [certificate] table (the number is not one: `issue`
    takes the next free one from the runs root's register)."""
    defaults: dict[str, Any] = dict(run.config.get("stand", {}).get("certificate", {}))
    dut = run.record.dut or DutIdentity()
    if dut.id:
        defaults.setdefault("dut_serial", dut.id)
    catalogue = dut.catalogue
    if catalogue:
        from sim.models import DUT_CATALOGUE

        model = DUT_CATALOGUE.get(catalogue)
        if model is not None:
            defaults.setdefault("dut_model", f"simulated {model.name} ({model.description})")
            defaults.setdefault("dut_type", f"{model.kind} accelerometer")
    defaults.setdefault("issue_date", run.record.finished_utc[:10])
    return defaults


def missing_items(info: CertificateInfo) -> list[str]:
    """Mandatory items not given (None, empty or only blanks), each with its option."""
    return [
        f"{name} ({option})"
        for name, option in MANDATORY
        if getattr(info, name) is None or not str(getattr(info, name)).strip()
    ]


TEMPERATURE_RANGE_C = (-50.0, 150.0)  # ambient of a calibration, incl. climatic chambers
ISO_DATE = re.compile(r"^\d{4}-\d{2}-\d{2}$")


def invalid_items(info: CertificateInfo) -> list[str]:
    """Items given but unusable, each naming its field and option: a temperature that is not a
    finite number in TEMPERATURE_RANGE_C, an issue date that is not an ISO date (yyyy-mm-dd)."""
    problems = []
    t = info.temperature_c
    if t is not None:
        low, high = TEMPERATURE_RANGE_C
        try:
            value = float(t)
        except (TypeError, ValueError):
            value = math.nan
        if not (math.isfinite(value) and low <= value <= high):
            problems.append(
                f"temperature_c (--temperature): {t!r} is not a temperature in "
                f"[{low:g}, {high:g}] deg C"
            )
    d = info.issue_date
    if d not in (None, ""):
        try:
            ok = bool(ISO_DATE.match(str(d))) and date.fromisoformat(str(d)) is not None
        except ValueError:
            ok = False
        if not ok:
            problems.append(f"issue_date (--issue-date): {d!r} is not a date as yyyy-mm-dd")
    return problems


# --- drawing --------------------------------------------------------------------------------

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
TITLE = ParagraphStyle(
    "title", parent=STYLES["Title"], fontName=FONT_BOLD, fontSize=17, alignment=TA_CENTER
)
VERDICT = ParagraphStyle(
    "verdict",
    parent=STYLES["Title"],
    fontName=FONT_BOLD,
    fontSize=20,
    leading=24,
    alignment=TA_CENTER,
)
PHASE_NOT_STATED = "not stated (not corrected for the inter-channel delay)"
GRID = colors.Color(0.75, 0.75, 0.75)
BAND = colors.Color(0.78, 0.86, 0.97)
INK = colors.Color(0.1, 0.25, 0.55)


def _fit(text: str, font: str, size: float, width: float) -> str:
    """`text` shortened with '…' to fit `width` points in `font` at `size`."""
    if pdfmetrics.stringWidth(text, font, size) <= width:
        return text
    while text and pdfmetrics.stringWidth(text + "…", font, size) > width:
        text = text[:-1]
    return text.rstrip() + "…"


def _numbered_canvas(number: str, laboratory: str):
    """A canvas class that writes the header and 'page x of y' once all pages are known."""

    class NumberedCanvas(pdf_canvas.Canvas):
        def __init__(self, *args: Any, **kwargs: Any):
            kwargs["invariant"] = True
            kwargs["initialFontName"] = FONT  # else each page's preamble names Helvetica
            super().__init__(*args, **kwargs)
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
            room = (
                width
                - 36 * mm
                - pdfmetrics.stringWidth(right, FONT, 8.5)
                - 6 * mm  # a gap between the two
            )
            self.setFont(FONT_BOLD, 8.5)
            self.drawString(18 * mm, height - 12 * mm, _fit(laboratory, FONT_BOLD, 8.5, room))
            self.setFont(FONT, 8.5)
            self.drawRightString(width - 18 * mm, height - 12 * mm, right)
            self.setStrokeColor(GRID)
            self.line(18 * mm, height - 14 * mm, width - 18 * mm, height - 14 * mm)
            self.line(18 * mm, 16 * mm, width - 18 * mm, 16 * mm)
            self.setFont(FONT, 7.5)
            self.drawString(
                18 * mm,
                11.5 * mm,
                "The results relate only to the item calibrated. This certificate shall not be "
                "reproduced except in full without the laboratory's written approval.",
            )
            self.drawRightString(
                width - 18 * mm,
                7.5 * mm,
                f"Certificate {number}   page {self._pageNumber} of {total}",
            )

    return NumberedCanvas


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


def _table(
    rows: list[list[Any]], widths: list[float], header: bool = True, size: float = 8
) -> Table:
    table = Table(rows, colWidths=widths, repeatRows=1 if header else 0, hAlign="LEFT")
    style = [
        ("FONTNAME", (0, 0), (-1, -1), FONT),
        ("FONTSIZE", (0, 0), (-1, -1), size),
        ("LEADING", (0, 0), (-1, -1), size + 2),
        ("VALIGN", (0, 0), (-1, -1), "TOP"),
        ("LINEBELOW", (0, 0), (-1, 0 if header else -1), 0.5, colors.black if header else GRID),
        ("BOTTOMPADDING", (0, 0), (-1, -1), 1.5),
        ("TOPPADDING", (0, 0), (-1, -1), 1.5),
    ]
    if header:
        style += [
            ("FONTNAME", (0, 0), (-1, 0), FONT_BOLD),
            ("ALIGN", (1, 1), (-1, -1), "RIGHT"),
        ]
    table.setStyle(TableStyle(style))
    return table


def _kv(rows: list[tuple[str, str]]) -> Table:
    data = [[Paragraph(f"<b>{k}</b>", BODY), Paragraph(v, BODY)] for k, v in rows]
    table = Table(data, colWidths=[48 * mm, 126 * mm], hAlign="LEFT")
    table.setStyle(
        TableStyle(
            [
                ("FONTNAME", (0, 0), (-1, -1), FONT),
                ("VALIGN", (0, 0), (-1, -1), "TOP"),
                ("BOTTOMPADDING", (0, 0), (-1, -1), 1),
                ("TOPPADDING", (0, 0), (-1, -1), 1),
            ]
        )
    )
    return table


def _dof(value: float) -> str:
    return "∞" if not math.isfinite(value) or value > 1e4 else f"{value:.0f}"


def _esc(text: Any) -> str:
    return str(text).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


# --- the certificate ------------------------------------------------------------------------


def load_sweep(path: str | Path, run: StoredRun) -> dict[str, Any]:
    """A complete sweep summary that includes `run`; CertificateError otherwise."""
    path = Path(path)
    try:
        check_input_file(path, MAX_TEXT_BYTES, "sweep summary")
    except InputFileError as exc:
        raise CertificateError(f"--sweep {exc}") from None
    try:
        sweep = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise CertificateError(f"--sweep {path}: cannot be read ({exc})") from None
    if sweep.get("status") != RunStatus.COMPLETE or "sensitivity_mv_per_ms2" not in sweep:
        raise CertificateError(f"--sweep {path}: the sweep is not complete")
    if run.record.run_id not in sweep.get("run_ids", []):
        raise CertificateError(f"--sweep {path}: does not include run {run.record.run_id}")
    return sweep


def build(
    run_path: str | Path,
    info: CertificateInfo,
    out: str | Path,
    sweep_path: str | Path | None = None,
) -> Path:
    """Write the certificate of a stored complete run to `out` (with the sweep it belongs to,
    if given: sensitivity against level and the linearity figure); returns the path. See
    `issue`."""
    issue(run_path, info, out, sweep_path)
    return Path(out)


def issue(
    run_path: str | Path,
    info: CertificateInfo,
    out: str | Path,
    sweep_path: str | Path | None = None,
    signer: Any = None,
) -> Issued:
    """Issue the certificate of a stored, verified, complete run: a number unique under the
    runs root (the run folder's parent; default AC-<run id>, then AC-<run id>-2, ...), the PDF
    written atomically to `out` and entered in the root's certificate register. Refused
    (CertificateError, nothing written) when the run does not verify or did not complete, an
    item is missing, `out` exists or would change a run's record, the number was issued before,
    or another certificate of the run is being issued."""
    run = load_stored_run(run_path)
    sweep = load_sweep(sweep_path, run) if sweep_path is not None else None
    info = info.merged(default_info(run))
    missing = missing_items(info)
    if missing:
        raise CertificateError(f"missing mandatory item(s): {', '.join(missing)}")
    invalid = invalid_items(info)
    if invalid:
        raise CertificateError(f"invalid item(s): {'; '.join(invalid)}")
    out = Path(out)
    into_run = _check_out(out, run.path)
    lock = try_lock(run.path)
    if lock is None:
        raise CertificateError(
            f"{run.path}: another certificate is being issued for this run; try again when it "
            "is done"
        )
    try:
        with locked_register(run.path.resolve().parent) as register:
            info = _numbered(info, run, register)
            xml = _dcc_of(run, info)  # validated before anything is written
            xml_out = dcc_path(out)
            wrote_xml = False
            with writable_folder(run.path) if into_run else contextlib.nullcontext():
                try:
                    if xml is not None:
                        write_with(xml_out, lambda path: _write_read_only(path, xml))
                        wrote_xml = True
                    write_with(out, lambda path: _write_pdf(run, info, sweep, path, xml, signer))
                except FileExistsRefusal as exc:
                    if wrote_xml:
                        xml_out.unlink(missing_ok=True)
                    raise CertificateError(
                        f"{exc}; a certificate is never overwritten (use --out)"
                    ) from None
                except BaseException:
                    if wrote_xml:
                        xml_out.unlink(missing_ok=True)
                    raise
                try:
                    return register.add(
                        str(info.certificate_number), _run_id(run), out.resolve(), sha256_of(out)
                    )
                except BaseException:
                    out.unlink(missing_ok=True)  # never a certificate the register lacks
                    if wrote_xml:
                        xml_out.unlink(missing_ok=True)
                    raise
    except RegisterError as exc:
        raise CertificateError(str(exc)) from None
    finally:
        unlock(lock)


def dcc_path(pdf: Path) -> Path:
    """Where the digital calibration certificate of `pdf` goes: beside it, .xml."""
    return pdf.with_suffix(".xml")


def _dcc_of(run: StoredRun, info: CertificateInfo) -> bytes | None:
    """The run's DCC XML (validated), or None when the stand file names no laboratory country
    (the PDF is still issued; the CLI says why there is no DCC). CertificateError otherwise."""
    from app.certificate.dcc import DccError, DccNotApplicable, build

    try:
        return build(run, info)
    except DccNotApplicable:
        return None
    except DccError as exc:
        raise CertificateError(str(exc)) from None


def _write_read_only(path: Path, data: bytes) -> None:
    path.write_bytes(data)
    path.chmod(0o444)


def _embed(pdf: Path, name: str, data: bytes) -> None:
    """Attach `data` to the PDF as an associated file (PDF/A-3 style: /AF in the catalogue,
    /AFRelationship /Data on the file specification), in place."""
    from pypdf import PdfWriter
    from pypdf.generic import ArrayObject, NameObject

    writer = PdfWriter(clone_from=str(pdf))
    writer.add_attachment(name, data)
    names = writer.root_object["/Names"]["/EmbeddedFiles"]["/Names"]  # type: ignore[index]
    spec = names[-1].get_object()
    spec[NameObject("/AFRelationship")] = NameObject("/Data")
    writer.root_object[NameObject("/AF")] = ArrayObject([names[-1]])
    with pdf.open("wb") as handle:
        writer.write(handle)


def _run_id(run: StoredRun) -> str:
    return str(run.record.run_id or run.path.name)


def _exists(out: Path) -> str:
    return f"{out}: exists; a certificate is never overwritten (use --out)"


def _check_out(out: Path, run_path: Path) -> bool:
    """Whether `out` goes into the run's own folder (as a certificate*.pdf product); refuses an
    existing file and any other place in a run folder (that would change a run's record)."""
    folder = out.resolve().parent
    if folder == run_path.resolve():
        if not is_product_name(out.name):
            raise CertificateError(
                f"--out: {out}: in the run folder only certificate*.pdf may be added (anything "
                "else would change the run's record)"
            )
    elif is_run_folder(folder):
        raise CertificateError(
            f"--out: {out}: inside the folder of another run ({folder}); a run's record is "
            "never changed"
        )
    if out.exists():
        raise CertificateError(_exists(out))
    if folder != run_path.resolve():
        out.parent.mkdir(parents=True, exist_ok=True)
        return False
    return True


def _numbered(info: CertificateInfo, run: StoredRun, register: Register) -> CertificateInfo:
    """`info` with its certificate number: the one given if never issued under the register's
    root, else the run's next default number."""
    number = info.certificate_number
    if number in (None, ""):
        return dataclasses.replace(info, certificate_number=register.next_number(_run_id(run)))
    issued = register.find(str(number))
    if issued is not None:
        raise CertificateError(
            f"--certificate-number: {number} is already used: it was issued on "
            f"{issued.issued_utc} for run {issued.run_id} ({issued.file}); a certificate "
            "number is never reused"
        )
    return info


def _write_pdf(
    run: StoredRun,
    info: CertificateInfo,
    sweep: dict[str, Any] | None,
    out: Path,
    dcc_xml: bytes | None = None,
    signer: Any = None,
) -> None:
    """Draw the certificate PDF of `run` with `info` (numbered) to `out`, read-only, with the
    DCC XML attached when given, signed last with `signer` (app.certificate.sign.Signer) when
    given."""
    record, results = run.record, run.results
    stand = record.stand
    lab = dict(stand.laboratory)
    reference = dict(stand.reference)
    plan = dict(record.plan)
    number = str(info.certificate_number)  # numbered before the PDF is made (_numbered)
    story: list[Any] = []
    r = results.reference
    value, u_value = fmt.round_gum(r.sensitivity_mv_per_ms2, r.expanded_uncertainty_mv_per_ms2)
    phase, u_phase = fmt.round_gum(r.phase_deg, r.phase_expanded_uncertainty_deg)
    p_percent = f"{100 * results.coverage_probability:.2f} %"

    story += [
        Paragraph("CALIBRATION CERTIFICATE", TITLE),
        Paragraph(
            f"<b>{_esc(lab.get('name', ''))}</b><br/>{_esc(lab.get('address', ''))}"
            + (f"<br/>{_esc(lab['accreditation'])}" if lab.get("accreditation") else ""),
            ParagraphStyle("lab", parent=BODY, alignment=TA_CENTER),
        ),
        Spacer(1, 4 * mm),
        _kv(
            [
                ("Certificate number", _esc(number)),
                (
                    "Customer",
                    _esc(info.customer)
                    + (f", {_esc(info.customer_address)}" if info.customer_address else ""),
                ),
                ("Item calibrated", f"{_esc(info.dut_type)}: {_esc(info.dut_model)}"),
                ("Serial number", _esc(info.dut_serial)),
                ("Date of calibration", _esc(record.started_utc[:10])),
                ("Date of issue", _esc(info.issue_date)),
                ("Calibration run", _esc(record.run_id)),
            ]
        ),
        Paragraph("Method", HEAD),
        Paragraph(_method_text(record, results, plan), BODY),
        Paragraph("Conditions", HEAD),
        _kv(
            [
                ("Ambient temperature", f"{float(info.temperature_c or 0.0):.1f} °C"),
                ("Mounting", _esc(info.mounting)),
                ("Excitation level", f"{record.level_ms2 or 0:g} m/s² peak per frequency"),
            ]
        ),
        Paragraph("Reference standard and traceability", HEAD),
        _kv(
            [
                (
                    "Reference standard",
                    f"{_esc(reference.get('model', ''))}, "
                    f"serial {_esc(reference.get('serial', ''))} "
                    f"(id {_esc(reference.get('id', ''))})",
                ),
                (
                    "Its calibration",
                    f"certificate {_esc(reference.get('certificate_number', ''))} of "
                    f"{_esc(reference.get('certificate_date', ''))}, traceable to national "
                    "standards",
                ),
            ]
        ),
        Paragraph("Result at the reference frequency", HEAD),
        _kv(
            [
                ("Reference frequency", f"{r.frequency_hz:g} Hz"),
                (
                    "Sensitivity",
                    f"<b>({value} ± {u_value}) mV/(m/s²)</b>, i.e. "
                    f"{r.sensitivity_db:.2f} dB re 1 mV/(m/s²)",
                ),
                (
                    "Phase",
                    f"({phase} ± {u_phase})°"
                    if results.phase_corrected_for_skew
                    else PHASE_NOT_STATED,
                ),
                ("Coverage", f"k = {r.coverage_factor:.2f}, coverage probability {p_percent}"),
            ]
        ),
    ]
    story += _verdict_section(results)
    story += _line_table(results)
    story += _charts(results)
    if sweep is not None:
        story += _sweep_section(sweep)
    story += _budget_section(run, results)
    story += _statements(results, info, p_percent)
    story += _sign_off(info, record)
    document = SimpleDocTemplate(
        str(out),
        pagesize=A4,
        leftMargin=18 * mm,
        rightMargin=18 * mm,
        topMargin=20 * mm,
        bottomMargin=22 * mm,
        title=f"Calibration certificate {number}",
        author=lab.get("name", ""),
        subject=f"{info.dut_model} serial {info.dut_serial}",
        creator=f"accelcal {record.software_version}",
    )
    document.build(story, canvasmaker=_numbered_canvas(number, lab.get("name", "")))
    if dcc_xml is not None:
        _embed(out, "certificate.xml", dcc_xml)
    if signer is not None:
        signer.sign_in_place(out, reason=f"Calibration certificate {number}")
    out.chmod(0o444)


def _verdict_section(results: Results) -> list[Any]:
    """The overall verdict, large and plain, with its reasons (app.procedure.verdict)."""
    if results.verdict is None:
        return []
    reasons = "<br/>".join(f"• {_esc(reason)}" for reason in results.verdict_reasons)
    return [
        Paragraph("Overall verdict", HEAD),
        Paragraph(f"<b>{_esc(results.verdict)}</b>", VERDICT),
        Paragraph(
            "Decision rule: guarded acceptance (ILAC-G8) against the DUT's tolerances; "
            "INDETERMINATE where a result is inside its tolerance only without its uncertainty, "
            "where no uncertainty or tolerance is stated, or where the mounting is in doubt.",
            SMALL,
        ),
        Paragraph(reasons, SMALL),
    ]


def _method_text(record: RunRecord, results: Results, plan: dict[str, Any]) -> str:
    lines = plan.get("lines", [])
    freqs = [ln["nominal_frequency_hz"] for ln in lines]
    span = f"{min(freqs):g} Hz to {max(freqs):g} Hz" if freqs else ""
    period_s = plan.get("period_samples", 0) / plan.get("sample_rate_hz", 1)
    excitation = (
        f"multisine excitation: {len(freqs)} frequencies at once (ISO 266 one-third-octave "
        f"values, {span}), each on a DFT bin of a {period_s:g} s "
        f"period sampled at {plan.get('sample_rate_hz', 0):g} Hz, phases optimised for a low "
        "crest factor, table acceleration equalised per frequency in closed loop"
        if record.mode == MODE_MULTISINE
        else f"stepped-sine excitation: {len(freqs)} frequencies one at a time ({span}), "
        "three-parameter sine fits (IEEE 1057)"
    )
    return (
        "Calibration by comparison with a reference transducer according to ISO 16063-21, "
        f"{excitation}. The sensitivity is the ratio of the DUT's and the reference's spectra "
        f"({results.estimator} estimator, {results.periods} periods averaged) times the reference "
        "chain's certified sensitivity, corrected for the conditioning gains and the DAQ's "
        f"inter-channel delay. Excitation time {record.excitation_time_s:.0f} s."
    )


def _line_table(results: Results) -> list[Any]:
    header = [
        "Nominal\nfrequency\nHz",
        "Actual\nfrequency\nHz",
        "Sensitivity\nmV/(m/s²)",
        "U\nmV/(m/s²)",
        "Deviation\n%",
        "Deviation\ndB",
        "Phase\n°",
        "U phase\n°",
        "U rel.\n%",
        "k",
        "ISO\n16063-21",
    ]
    rows = [header]
    printed = line_values(results)  # the strings the DCC carries too
    for i, ln in enumerate(results.lines):
        s, u = printed["s"][i], printed["u"][i]
        ph, u_ph = printed["ph"][i], printed["u_ph"][i]
        if not results.phase_corrected_for_skew:
            ph, u_ph = "n/s", "n/s"
        rel = 100 * ln.relative_expanded_uncertainty
        dev_decimals = (
            max(0, -math.floor(math.log10(rel)) + 1) if rel > 0 and math.isfinite(rel) else 2
        )
        rows.append(
            [
                f"{ln.nominal_frequency_hz:g}",
                printed["f"][i],
                s,
                u,
                fmt.signed(ln.deviation_percent, dev_decimals),
                fmt.signed(ln.deviation_db, 3),
                ph,
                u_ph,
                fmt.significant(rel),
                printed["k"][i],
                {"within": "within", "over": "over", "n/a": "n/a", NOT_STATED: "n/s"}[
                    ln.iso_verdict
                ],
            ]
        )
    widths = [w * mm for w in (15, 15, 19, 16, 16, 16, 15, 14, 13, 11, 16)]
    table = _table(rows, widths, size=7.3)
    note = Paragraph(
        "Deviation: sensitivity relative to the sensitivity at the reference frequency. "
        "U: expanded "
        "uncertainty with the coverage factor k of its line. ISO 16063-21: relative expanded "
        "uncertainty within the standard's suggested limits (2 % to 1 kHz, 4 % to 2 kHz, 6 % "
        "to 10 kHz) or over them; n/s: not stated (no expanded uncertainty"
        + ("" if results.phase_corrected_for_skew else "; phase: " + PHASE_NOT_STATED)
        + ").",
        SMALL,
    )
    return [Paragraph("Results per frequency", HEAD), table, Spacer(1, 1.5 * mm), note]


def _charts(results: Results) -> list[Any]:
    f = [ln.frequency_hz for ln in results.lines]
    deviation = [ln.deviation_percent for ln in results.lines]
    u_dev = [
        100 * ln.relative_expanded_uncertainty * (1 + ln.deviation_percent / 100)
        for ln in results.lines
    ]
    phase = [ln.phase_deg for ln in results.lines]
    u_phase = [ln.phase_expanded_uncertainty_deg for ln in results.lines]
    if not results.phase_corrected_for_skew:  # no phase characteristic without the skew
        return [
            KeepTogether(
                [
                    Paragraph("Amplitude-frequency characteristic", HEAD),
                    chart(f, deviation, u_dev, "deviation in %"),
                    Paragraph(f"Phase-frequency characteristic: {PHASE_NOT_STATED}.", BODY),
                    Paragraph("Shaded: the expanded uncertainty (k as in the table).", SMALL),
                ]
            )
        ]
    return [
        KeepTogether(
            [
                Paragraph("Amplitude-frequency characteristic", HEAD),
                chart(f, deviation, u_dev, "deviation in %"),
                Paragraph("Phase-frequency characteristic", HEAD),
                chart(f, phase, u_phase, "phase in degrees"),
                Paragraph("Shaded: the expanded uncertainty (k as in the table).", SMALL),
            ]
        )
    ]


def _sweep_section(sweep: dict[str, Any]) -> list[Any]:
    """Sensitivity against frequency and level (mV/(m/s^2)) and linearity per frequency."""
    levels = sweep["levels_ms2"]
    table = sweep["sensitivity_mv_per_ms2"]
    header = ["Frequency\nHz", *(f"{lv:g} m/s²" for lv in levels), "Linearity\n%"]
    rows = [header]
    for k, f in enumerate(sweep["frequencies_hz"]):
        rows.append(
            [
                f"{f:g}",
                *(f"{row[k]:.4g}" for row in table),
                fmt.significant(sweep["linearity_percent"][k]),
            ]
        )
    width = 150 / (len(levels) + 2)
    return [
        Paragraph("Sensitivity against excitation level (mV/(m/s²))", HEAD),
        _table(rows, [width * mm] * (len(levels) + 2), size=7.3),
        Spacer(1, 1.5 * mm),
        Paragraph(
            f"Linearity: largest deviation of the sensitivity at any level from its mean over "
            f"the levels: {fmt.significant(sweep['reference_linearity_percent'])} % at "
            f"{sweep['reference_frequency_hz']:g} Hz, at most "
            f"{fmt.significant(sweep['worst_linearity_percent'])} % (at "
            f"{sweep['worst_linearity_frequency_hz']:g} Hz). Levels are peak accelerations per "
            f"frequency; runs {', '.join(sweep['run_ids'])}.",
            SMALL,
        ),
    ]


def _budget_section(run: StoredRun, results: Results) -> list[Any]:
    r = results.reference
    line = next(ln for ln in results.lines if ln.nominal_frequency_hz == r.frequency_hz)
    rows = [["Component", "Value", "Distribution", "Standard\nuncertainty", "Degrees of\nfreedom"]]
    rows.append(
        [
            "Repeatability (type A, this calibration)",
            "",
            "normal (t)",
            f"{100 * line.relative_type_a:.3g} %",
            f"{2 * (results.periods - 1)}",
        ]
    )
    for c in run.budget.at(line.frequency_hz, Quantity.MAGNITUDE):
        rows.append(
            [
                Paragraph(_esc(c.name), SMALL),
                f"{100 * c.value:.3g} %",
                str(c.distribution),
                f"{100 * c.standard_uncertainty:.3g} %",
                _dof(c.dof),
            ]
        )
    rows.append(
        [
            "Combined standard uncertainty",
            "",
            "",
            f"{100 * line.relative_standard_uncertainty:.3g} %",
            _dof(line.effective_dof),
        ]
    )
    rows.append(
        [
            f"Expanded uncertainty (k = {line.coverage_factor:.2f})",
            "",
            "",
            f"{fmt.significant(100 * line.relative_expanded_uncertainty)} %",
            "",
        ]
    )
    table = _table(rows, [w * mm for w in (78, 18, 24, 26, 22)], size=7.5)
    return [
        KeepTogether(
            [
                Paragraph(f"Uncertainty budget of the sensitivity at {r.frequency_hz:g} Hz", HEAD),
                table,
            ]
        )
    ]


def _statements(results: Results, info: CertificateInfo, p_percent: str) -> list[Any]:
    out = [
        Paragraph("Uncertainty statement", HEAD),
        Paragraph(
            "The reported expanded uncertainty of measurement is stated as the standard "
            "uncertainty of measurement multiplied by the coverage factor k, which for a "
            f"t-distribution with the effective degrees of freedom (Welch-Satterthwaite) "
            f"corresponds to a coverage probability of {p_percent}. It has been determined in "
            "accordance with JCGM 100:2008 (GUM) and ISO 16063-21."
            if results.uncertainty_rule == "gum"
            else "The expanded uncertainty uses the coverage factor rule of the method's source: "
            "Student's t at 95 % with L - 1 degrees of freedom for fewer than 10 periods, "
            "otherwise k = 2.",
            BODY,
        ),
    ]
    if results.tolerance_percent is not None:
        verdicts = [ln.tolerance_verdict for ln in results.lines]
        summary = (
            "conforms"
            if all(v == "pass" for v in verdicts)
            else "does not conform"
            if any(v == "fail" for v in verdicts)
            else "conformity not stated (no expanded uncertainty stated at "
            f"{verdicts.count(NOT_STATED)} frequencies)"
            if NOT_STATED in verdicts
            else "no statement of conformity can be made at every frequency"
        )
        out += [
            Paragraph("Statement of conformity", HEAD),
            Paragraph(
                f"Specification: deviation of the sensitivity from its value at the reference "
                f"frequency within ±{results.tolerance_percent:g} %. Decision rule: guarded "
                "acceptance (ILAC-G8): pass where |deviation| + U ≤ tolerance, fail where "
                "|deviation| − U > tolerance, otherwise inconclusive. Result: the item "
                f"<b>{summary}</b> ({verdicts.count('pass')} pass, {verdicts.count('fail')} "
                f"fail, {verdicts.count('inconclusive')} inconclusive, "
                f"{verdicts.count(NOT_STATED)} not stated of {len(verdicts)}).",
                BODY,
            ),
        ]
    if info.notes:
        out += [Paragraph("Notes", HEAD), Paragraph(_esc(info.notes), BODY)]
    return out


def _sign_off(info: CertificateInfo, record: RunRecord) -> list[Any]:
    return [
        Spacer(1, 6 * mm),
        KeepTogether(
            [
                _kv(
                    [
                        (
                            "Authorised by",
                            f"{_esc(info.authorised_by)}<br/><br/>"
                            "signature: ______________________",
                        ),
                        ("Date of issue", _esc(info.issue_date)),
                        ("Software", f"accelcal {_esc(record.software_version)}"),
                        (
                            "Raw data SHA-256",
                            f"<font size=7>{_esc(record.raw_data_sha256 or '')}</font>",
                        ),
                    ]
                ),
                Spacer(1, 2 * mm),
                Paragraph("The results relate only to the item calibrated.", BODY),
            ]
        ),
    ]
