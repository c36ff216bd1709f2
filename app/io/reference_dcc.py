"""A reference standard's calibration as its laboratory's DCC states it (PTB DCC 3.x, D-SI):
read (`accelcal refs add --dcc`, the GUI's reference dialog), validated against the schema set
shipped in app/data/dcc, its XML signature verified when it has one (app.io.dcc_signature),
checked to be a vibration transducer's calibration, and its frequency-dependent sensitivity
table taken in the records' units: Hz, mV/(m/s^2) (pC/(m/s^2) at 1 mV/pC), the relative
expanded uncertainty as a fraction at k = 2, phase in degrees.

The table may come in the shapes laboratories use: parallel lists (si:realListXMLList, alone or
in si:hybrid), or a dcc:list per frequency point holding si:real quantities; quantities are
recognised by their units (app.io.dsi_units), a quantity named a sensitivity or phase in a unit
that is not one is refused. Every refusal names the element (an XPath-like path) and why.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
from dataclasses import dataclass, field
from datetime import date
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.errors import Refusal
from app.io.checks import MIB, InputFileError, read_regular_bytes
from app.io.dsi_units import Kind, Unit, parse_unit

if TYPE_CHECKING:
    from lxml.etree import _Element

    from app.io.dcc_signature import Signature
    from app.io.reference_table import TableRow

DCC_NS = "https://ptb.de/dcc"
SI_NS = "https://ptb.de/si"
DS_NS = "http://www.w3.org/2000/09/xmldsig#"
PREFIXES = {DCC_NS: "dcc", SI_NS: "si", DS_NS: "ds"}
MAX_DCC_BYTES = 16 * MIB
MAX_POINTS = 1000
# words that make a DCC a vibration transducer's calibration (item, method, result names)
VIBRATION_WORDS = (
    "16063", "acceleromet", "acceleration", "vibration", "beschleunigung", "schwingung",
    "accéléromètre", "accelerometro", "acelerómetro",
)  # fmt: skip
# words that make a quantity named for a sensitivity something else (checked by unit only)
NOT_THE_TABLE = (
    "deviation", "relative", "ratio", "transverse", "uncertainty", "linearity", "temperature",
    "abweichung", "querempfindlich",
)  # fmt: skip


class ReferenceDccError(Refusal):
    """A reference DCC refused; the message names the option, the file, the element and why."""


@dataclass(frozen=True)
class DccPoint:
    """One frequency of the table as stated: Hz, mV/(m/s^2) with its expanded U and k (k None:
    a coverage interval, U its half-width), degrees with its U when stated."""

    frequency_hz: float
    sensitivity_mv_per_ms2: float
    expanded_uncertainty_mv_per_ms2: float
    coverage_factor: float | None
    relative_expanded_uncertainty: float  # fraction, at k = 2 (what the records keep)
    phase_deg: float | None = None
    phase_expanded_uncertainty_deg: float | None = None


@dataclass(frozen=True)
class ReferenceDcc:
    """A reference standard's DCC as read: identity, dates (ISO), laboratory, item, table,
    signature, the file's SHA-256 and bytes."""

    unique_identifier: str
    laboratory: str
    manufacturer: str
    model: str
    serial: str
    begin_date: date
    end_date: date
    issue_date: date | None
    points: tuple[DccPoint, ...]
    sensitivity_unit: str
    charge: bool
    signature: Signature
    sha256: str
    content: bytes = field(repr=False)
    file_name: str = ""

    @property
    def calibration_date(self) -> date:
        """The calibration's date: the DCC's endPerformanceDate."""
        return self.end_date

    def table(self) -> list[TableRow]:
        """The table as the records take it (app.io.reference_table.TableRow)."""
        return [
            (p.frequency_hz, p.sensitivity_mv_per_ms2, p.relative_expanded_uncertainty, p.phase_deg)
            for p in self.points
        ]

    def identity_line(self) -> str:
        """`DCC <uniqueIdentifier> of <laboratory>, SHA-256 <hex>` as certificates print it."""
        return f"DCC {self.unique_identifier} of {self.laboratory}, SHA-256 {self.sha256}"


def read_reference_dcc(
    path: Path, option: str = "--dcc", certificate: Path | None = None
) -> ReferenceDcc:
    """The reference DCC at `path` (module docstring), its signature checked against
    `certificate` (PEM) when given, else the certificate it embeds. ReferenceDccError."""
    try:
        data = read_regular_bytes(path, MAX_DCC_BYTES, "DCC")
        pem = None if certificate is None else read_regular_bytes(certificate, MIB, "certificate")
    except (InputFileError, OSError) as exc:
        raise ReferenceDccError(f"{option}: {exc}") from None
    return parse_reference_dcc(data, f"{option}: {path}", pem, file_name=path.name)


def parse_reference_dcc(
    data: bytes, source: str, certificate_pem: bytes | None = None, *, file_name: str = ""
) -> ReferenceDcc:
    """`data` read as a reference DCC; refusals begin with `source` (option and file)."""
    from lxml import etree

    from app.io.dcc_signature import SignatureError, verify_signature

    parser = etree.XMLParser(
        resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False
    )
    try:
        root = etree.fromstring(data, parser)
    except etree.XMLSyntaxError as exc:
        raise ReferenceDccError(f"{source}: not well-formed XML ({exc})") from None
    if root.getroottree().docinfo.doctype:  # entities, external references: never in a DCC
        raise ReferenceDccError(f"{source}: a DOCTYPE (DTD) is not allowed in a DCC")
    if root.tag != f"{{{DCC_NS}}}digitalCalibrationCertificate":
        raise ReferenceDccError(
            f"{source}: /{_name(root)}: the root is not dcc:digitalCalibrationCertificate "
            f"({DCC_NS}): not a DCC"
        )
    error = next(iter(_schema().iter_errors(root)), None)
    if error is not None:
        where = error.path or "/" + _name(root)
        raise ReferenceDccError(
            f"{source}: {where}: not valid against the DCC schema "
            f"{root.get('schemaVersion', '')}: {error.reason or error.message}"
        )
    try:
        signature = verify_signature(data, root, certificate_pem)
    except SignatureError as exc:
        raise ReferenceDccError(f"{source}: {exc}") from None
    reader = _Reader(root, source)
    reader.check_vibration()
    points, unit = reader.table()
    manufacturer, model, serial = reader.item()
    return ReferenceDcc(
        unique_identifier=reader.text("dcc:administrativeData/dcc:coreData/dcc:uniqueIdentifier"),
        laboratory=reader.laboratory(),
        manufacturer=manufacturer,
        model=model,
        serial=serial,
        begin_date=reader.required_date("beginPerformanceDate"),
        end_date=reader.required_date("endPerformanceDate"),
        issue_date=reader.optional_date("issueDate"),
        points=points,
        sensitivity_unit=unit.text,
        charge=unit.kind is Kind.CHARGE_SENSITIVITY,
        signature=signature,
        sha256=hashlib.sha256(data).hexdigest(),
        content=data,
        file_name=file_name,
    )


@functools.cache
def _schema() -> Any:
    """The DCC schema set shipped in app/data/dcc (offline; PTB's, LGPL-3)."""
    import xmlschema

    base = resources.files("app").joinpath("data", "dcc")
    locations = [
        (SI_NS, str(base.joinpath("SI_Format.xsd"))),
        (DS_NS, str(base.joinpath("xmldsig-core-schema.xsd"))),
        ("http://qudt.org/vocab/", str(base.joinpath("quantitykind.xsd"))),
    ]
    return xmlschema.XMLSchema(str(base.joinpath("dcc.xsd")), locations=locations, allow="local")


def _name(element: _Element) -> str:
    qname = str(element.tag)
    if qname.startswith("{"):
        ns, local = qname[1:].split("}", 1)
        return f"{PREFIXES.get(ns, ns)}:{local}"
    return qname


def element_path(element: _Element) -> str:
    """An XPath-like path of `element` with dcc:/si:/ds: prefixes, an index where siblings
    share the name: /dcc:digitalCalibrationCertificate/dcc:measurementResults/..."""
    parts = []
    node: _Element | None = element
    while node is not None:
        parent = node.getparent()
        name = _name(node)
        if parent is not None:
            same = [child for child in parent if child.tag == node.tag]
            if len(same) > 1:
                name += f"[{same.index(node) + 1}]"
        parts.append(name)
        node = parent
    return "/" + "/".join(reversed(parts))


@dataclass
class _Series:
    """One quantity's values in one unit, with their uncertainty, where they were found."""

    element: _Element  # the dcc:quantity
    unit_element: _Element
    unit: Unit
    values: list[float]
    expanded: list[float] | None = None  # U, in the unit
    factors: list[float | None] | None = None  # k (None: a coverage interval's)


class _Reader:
    """Lookups in a schema-valid DCC, refusals naming the element."""

    def __init__(self, root: _Element, source: str) -> None:
        self.root, self.source = root, source
        self.ns = {"dcc": DCC_NS, "si": SI_NS}

    def refuse(self, element: _Element | str, why: str) -> ReferenceDccError:
        where = element if isinstance(element, str) else element_path(element)
        return ReferenceDccError(f"{self.source}: {where}: {why}")

    def text(self, path: str, required: bool = True) -> str:
        found = self.root.find(path, self.ns)
        value = "" if found is None else " ".join("".join(found.itertext()).split())
        if required and not value:
            raise self.refuse(f"/dcc:digitalCalibrationCertificate/{path}", "empty")
        return value

    def content(self, element: _Element | None) -> str:
        """The first dcc:content of a textType element (English preferred), else ''."""
        if element is None:
            return ""
        contents = element.findall("dcc:content", self.ns)
        english = [c for c in contents if c.get("lang") == "en"]
        chosen = (english or contents or [None])[0]
        return "" if chosen is None else " ".join("".join(chosen.itertext()).split())

    def required_date(self, tag: str) -> date:
        found = self.optional_date(tag)
        if found is None:
            raise self.refuse(f"/dcc:digitalCalibrationCertificate/{tag}", "no date")
        return found

    def optional_date(self, tag: str) -> date | None:
        path = f"dcc:administrativeData/dcc:coreData/dcc:{tag}"
        text = self.text(path, required=False)
        if not text:
            return None
        try:
            return date.fromisoformat(text[:10])
        except ValueError:
            raise self.refuse(
                f"/dcc:digitalCalibrationCertificate/{path}", f"not a date: {text!r}"
            ) from None

    def laboratory(self) -> str:
        lab = self.root.find("dcc:administrativeData/dcc:calibrationLaboratory", self.ns)
        assert lab is not None  # the schema requires it
        name = self.content(lab.find("dcc:contact/dcc:name", self.ns))
        code = lab.findtext("dcc:calibrationLaboratoryCode", "", self.ns).strip()
        if not (name or code):
            raise self.refuse(lab, "the calibrating laboratory has no name")
        return f"{name} ({code})" if name and code and code not in name else name or code

    def item(self) -> tuple[str, str, str]:
        """Manufacturer, model and serial of the first item (serial: an identification of
        refType basic_serialNumber, else one named serial, else the manufacturer's)."""
        item = self.root.find("dcc:administrativeData/dcc:items/dcc:item", self.ns)
        assert item is not None  # the schema requires one
        maker = self.content(item.find("dcc:manufacturer/dcc:name", self.ns))
        model = item.findtext("dcc:model", "", self.ns).strip()
        serial = ""
        for ident in item.findall("dcc:identifications/dcc:identification", self.ns):
            value = ident.findtext("dcc:value", "", self.ns).strip()
            named = self.content(ident.find("dcc:name", self.ns)).lower()
            if "basic_serialnumber" in (ident.get("refType") or "").lower() or "serial" in named:
                serial = value
                break
            if not serial and ident.findtext("dcc:issuer", "", self.ns) == "manufacturer":
                serial = value
        return maker, model, serial

    def check_vibration(self) -> None:
        """Refused unless the item, a method or a result names a vibration transducer or
        ISO 16063 (VIBRATION_WORDS)."""
        words: list[str] = []
        item = self.root.find("dcc:administrativeData/dcc:items/dcc:item", self.ns)
        for element in self.root.iter(f"{{{DCC_NS}}}content", f"{{{DCC_NS}}}norm"):
            parent = element.getparent()
            owner = parent.getparent() if parent is not None else None
            tags = {_name(x) for x in (parent, owner) if x is not None}
            if tags & {"dcc:item", "dcc:usedMethod", "dcc:measurementResult", "dcc:result"} or (
                _name(element) == "dcc:norm"
            ):
                words.append("".join(element.itertext()).lower())
        if not any(word in text for text in words for word in VIBRATION_WORDS):
            name = self.content(item.find("dcc:name", self.ns)) if item is not None else ""
            raise self.refuse(
                item if item is not None else "/dcc:digitalCalibrationCertificate",
                f"{name!r} is not a vibration transducer calibration (no ISO 16063 method, "
                "no accelerometer, acceleration or vibration in the item's, methods' or "
                "results' names)",
            )

    # ---- the table --------------------------------------------------------------------------
    def table(self) -> tuple[tuple[DccPoint, ...], Unit]:
        """The sensitivity table of the first result holding one (module docstring)."""
        results = self.root.findall(
            "dcc:measurementResults/dcc:measurementResult/dcc:results/dcc:result", self.ns
        )
        for result in results:
            roles = self._roles(result)
            if roles[Kind.VOLTAGE_SENSITIVITY] or roles[Kind.CHARGE_SENSITIVITY]:
                return self._points(result, roles)
        raise self.refuse(
            "/dcc:digitalCalibrationCertificate/dcc:measurementResults",
            "no sensitivity table (no quantity in V or pC per m/s^2 in any dcc:result)",
        )

    def _roles(self, result: _Element) -> dict[Kind, list[_Series]]:
        roles: dict[Kind, list[_Series]] = {kind: [] for kind in Kind}
        for quantity in result.iter(f"{{{DCC_NS}}}quantity"):
            series = self._series(quantity)
            if series is None:
                continue
            roles[series.unit.kind].append(series)
        return roles

    def _labels(self, quantity: _Element) -> str:
        return " ".join(
            (quantity.get("refType") or "", self.content(quantity.find("dcc:name", self.ns)))
        ).lower()

    def _series(self, quantity: _Element) -> _Series | None:
        """The quantity's values in the first unit that says what they are (si:real,
        si:realListXMLList, or the first such in an si:hybrid); a quantity named a
        sensitivity, phase or frequency whose unit is not one is refused."""
        labels = self._labels(quantity)
        named = next(
            (
                kind
                for kind, words in (
                    (Kind.ANGLE, ("phase",)),
                    (Kind.VOLTAGE_SENSITIVITY, ("sensitiv", "magnitude", "empfindlich")),
                    (Kind.FREQUENCY, ("frequen",)),
                )
                if any(w in labels for w in words)
            ),
            None,
        )
        if any(word in labels for word in NOT_THE_TABLE):
            named = None  # a relative deviation, a transverse sensitivity ratio, ...
        candidates = [
            child for child in quantity if _name(child) in ("si:real", "si:realListXMLList")
        ]
        hybrid = quantity.find("si:hybrid", self.ns)
        if hybrid is not None:
            candidates += [c for c in hybrid if _name(c) in ("si:real", "si:realListXMLList")]
        read = [self._read(c) for c in candidates]
        known = [s for s in read if s.unit.kind is not Kind.OTHER]
        if named is not None and not any(_fits(named, s.unit.kind) for s in known):
            unit = read[0].unit_element if read else quantity
            shown = read[0].unit.text if read else "none"
            what = {
                Kind.ANGLE: "an angle (\\degree, \\radian)",
                Kind.FREQUENCY: "a frequency (\\hertz)",
            }.get(named, "a sensitivity (\\volt or \\pico\\coulomb per \\metre\\second\\tothe{-2})")
            label = self.content(quantity.find("dcc:name", self.ns)) or quantity.get("refType")
            raise self.refuse(unit, f"unit '{shown}' of quantity '{label}' is not {what}")
        if named is not None:
            known = [s for s in known if _fits(named, s.unit.kind)]
        return known[0] if known else None

    def _read(self, element: _Element) -> _Series:
        """si:real or si:realListXMLList: values, unit (one or one per value), uncertainty."""
        listed = _name(element) == "si:realListXMLList"
        tag = "XMLList" if listed else ""
        unit_element = element.find(f"si:unit{tag}", self.ns)
        value_element = element.find(f"si:value{tag}", self.ns)
        assert unit_element is not None and value_element is not None  # the schema
        units = (unit_element.text or "").split() if listed else [unit_element.text or ""]
        parsed = [parse_unit(u) for u in units]
        if not parsed or any(p is None for p in parsed) or len({p.factor for p in parsed if p}) > 1:
            unit = Unit(" ".join(units), 1.0, Kind.OTHER)
        else:
            unit = parsed[0]  # type: ignore[assignment]
        values = self._numbers(value_element)
        series = _Series(element.getparent(), unit_element, unit, values)
        if listed:
            self._list_uncertainty(element, series)
        else:
            self._real_uncertainty(element, series)
        return series

    def _numbers(self, element: _Element, count: int | None = None) -> list[float]:
        try:
            numbers = [float(x) for x in (element.text or "").split()]
        except ValueError:
            raise self.refuse(element, "not a list of numbers") from None
        if count is not None and len(numbers) == 1:
            numbers *= count  # one value for every point (D-SI's XML lists)
        if count is not None and len(numbers) != count:
            raise self.refuse(element, f"{len(numbers)} values for {count} points")
        return numbers

    def _real_uncertainty(self, real: _Element, series: _Series) -> None:
        n = {"si": SI_NS}
        expanded = real.find("si:measurementUncertaintyUnivariate/si:expandedMU", n)
        legacy = real.find("si:expandedUnc", n)
        interval = real.find("si:measurementUncertaintyUnivariate/si:coverageIntervalMU", n)
        old_interval = real.find("si:coverageInterval", n)
        if expanded is not None or legacy is not None:
            node = expanded if expanded is not None else legacy
            assert node is not None
            value_tag = "si:valueExpandedMU" if expanded is not None else "si:uncertainty"
            series.expanded = self._numbers(node.find(value_tag, n), 1)  # type: ignore[arg-type]
            series.factors = list(self._numbers(node.find("si:coverageFactor", n), 1))  # type: ignore[arg-type]
        elif interval is not None or old_interval is not None:
            node = interval if interval is not None else old_interval
            assert node is not None
            low = self._numbers(node.find("si:intervalMin", n), 1)  # type: ignore[arg-type]
            high = self._numbers(node.find("si:intervalMax", n), 1)  # type: ignore[arg-type]
            series.expanded = [(high[0] - low[0]) / 2]
            series.factors = [None]

    def _list_uncertainty(self, real_list: _Element, series: _Series) -> None:
        n = {"si": SI_NS}
        count = len(series.values)
        base = "si:measurementUncertaintyUnivariateXMLList/"
        for path, value_tag in (
            (base + "si:expandedMUXMLList", "si:valueExpandedMUXMLList"),
            ("si:expandedUncXMLList", "si:uncertaintyXMLList"),
        ):
            node = real_list.find(path, n)
            if node is not None:
                series.expanded = self._numbers(node.find(value_tag, n), count)  # type: ignore[arg-type]
                factors = node.find("si:coverageFactorXMLList", n)
                series.factors = list(self._numbers(factors, count))  # type: ignore[arg-type]
                return
        for path in (base + "si:coverageIntervalMUXMLList", "si:coverageIntervalXMLList"):
            node = real_list.find(path, n)
            if node is not None:
                low = self._numbers(node.find("si:intervalMinXMLList", n), count)  # type: ignore[arg-type]
                high = self._numbers(node.find("si:intervalMaxXMLList", n), count)  # type: ignore[arg-type]
                series.expanded = [(h - lo) / 2 for lo, h in zip(low, high, strict=True)]
                series.factors = [None] * count
                return

    def _points(
        self, result: _Element, roles: dict[Kind, list[_Series]]
    ) -> tuple[tuple[DccPoint, ...], Unit]:
        magnitude = roles[Kind.VOLTAGE_SENSITIVITY] or roles[Kind.CHARGE_SENSITIVITY]
        frequency, phase = roles[Kind.FREQUENCY], roles[Kind.ANGLE]
        if not frequency:
            raise self.refuse(result, "a sensitivity table without frequencies (no \\hertz)")
        unit = magnitude[0].unit
        if any(s.unit.kind is not unit.kind for s in magnitude):
            raise self.refuse(result, "sensitivities in both volt and coulomb")
        for series in magnitude:
            if series.expanded is None:
                raise self.refuse(
                    series.element,
                    "a sensitivity without its expanded uncertainty (si:expandedMU with "
                    "coverageFactor, or a coverage interval)",
                )
        f = [s.unit.to_hz(v) for s in frequency for v in s.values]
        values = [(s, i) for s in magnitude for i in range(len(s.values))]
        angles = [(s, i) for s in phase for i in range(len(s.values))]
        if len(values) != len(f):
            raise self.refuse(result, f"{len(f)} frequencies but {len(values)} sensitivities")
        if angles and len(angles) != len(f):
            raise self.refuse(result, f"{len(f)} frequencies but {len(angles)} phases")
        if not 0 < len(f) <= MAX_POINTS:
            raise self.refuse(result, f"{len(f)} points (1 to {MAX_POINTS})")
        points = []
        for index, (hz, (series, i)) in enumerate(zip(f, values, strict=True)):
            points.append(self._point(result, index, hz, series, i, angles))
        for before, after in itertools.pairwise(points):
            if after.frequency_hz <= before.frequency_hz:
                raise self.refuse(
                    frequency[0].element,
                    f"frequencies must increase ({after.frequency_hz:g} Hz after "
                    f"{before.frequency_hz:g} Hz)",
                )
        return tuple(points), unit

    def _point(
        self,
        result: _Element,
        index: int,
        hz: float,
        series: _Series,
        i: int,
        angles: list[tuple[_Series, int]],
    ) -> DccPoint:
        assert series.expanded is not None and series.factors is not None
        s = series.unit.to_mv_per_ms2(series.values[i])
        u = series.unit.to_mv_per_ms2(series.expanded[i])
        k = series.factors[i]
        where = f"point {index + 1} ({hz:g} Hz)"
        if not (hz > 0 and s > 0 and u >= 0) or (k is not None and not k > 0):
            raise self.refuse(
                series.element, f"{where}: frequency, sensitivity and k must be > 0, U >= 0"
            )
        # the records keep U at k = 2 (a normal distribution): a stated U at k rescaled
        relative = u / s * (2.0 / k if k is not None else 1.0)
        if relative >= 1:
            raise self.refuse(series.element, f"{where}: U is {100 * relative:g} % of the value")
        phase = phase_u = None
        if angles:
            p_series, j = angles[index]
            phase = p_series.unit.to_degrees(p_series.values[j])
            if p_series.expanded is not None:
                phase_u = p_series.unit.to_degrees(p_series.expanded[j])
        return DccPoint(hz, s, u, k, relative, phase, phase_u)


def _fits(named: Kind, kind: Kind) -> bool:
    if named is Kind.VOLTAGE_SENSITIVITY:
        return kind in (Kind.VOLTAGE_SENSITIVITY, Kind.CHARGE_SENSITIVITY)
    return named is kind
