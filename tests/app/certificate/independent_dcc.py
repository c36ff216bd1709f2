"""An independent DCC validator and reader (issue 35 point 3), from the package index: dcclib
(PTB's XSD through libxml2, the DCC Schematron through Saxon) and its reader dcc-json-toolkit
(XML to a typed dict through the released schema), used offline.

Offline: dcc-json-toolkit reads the schema from its cache folder (`<cache>/<version>/dcc.xsd`,
imports rewritten to the cached files, as its CacheManager writes them) and fetches it from
ptb.de only when it is missing; `Independent.offline` places the schema this program ships
(app/data/dcc) there first, in a temporary cache, and every network call (requests,
urllib) fails while it is in use, so a test that passes read nothing from the web.

`read_back` reads what a machine needs, by refType only (never by name or place): each line's
frequency, sensitivity with U and k, phase with U, deviation with U; the per-point conformity
with its frequencies and tolerance limits; the decision rule; the run seal; the software
release; `expected` is the same read from the run's results.json and seal, for comparison.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

VERSION = "3.3.0"
SHIPPED = Path(__file__).resolve().parents[3] / "app" / "data" / "dcc"
IMPORTS = {  # the schema's imports (as published) -> the shipped file that answers each
    "dcc.xsd": {
        "https://ptb.de/si/v2.2.1/SI_Format.xsd": "SI_Format.xsd",
        "https://www.ptb.de/dcc/d-sig/xmldsig-core-schema.xsd": "xmldsig-core-schema.xsd",
    },
    "SI_Format.xsd": {
        "https://www.ptb.de/si/v2.2.1/qudt/quantitykind.xsd": "quantitykind.xsd",
    },
    "xmldsig-core-schema.xsd": {},
    "quantitykind.xsd": {},
}


def _no_network(*args: Any, **kwargs: Any) -> Any:
    raise AssertionError(f"the independent DCC validator went to the network: {args[:1]}")


@dataclass
class Independent:
    """dcclib's XSD and Schematron validators and dcc-json-toolkit's schema, built offline."""

    xsd: Any
    schematron: Any
    schema: Any

    @classmethod
    @contextmanager
    def offline(cls, cache: Path) -> Iterator[Independent]:
        """The validators, with the shipped schema placed in the tool's cache at `cache` and
        the network shut for as long as the block runs."""
        import urllib.request

        import requests
        from dcc_json_toolkit import cache as toolkit_cache

        folder = cache / VERSION
        folder.mkdir(parents=True)
        for name, imports in IMPORTS.items():
            text = (SHIPPED / name).read_text(encoding="utf-8")
            for url, local in imports.items():
                assert url in text, (name, url)  # the shipped schema imports what we answer
                uri = toolkit_cache.CacheManager.as_file_uri_path(folder / local)
                text = text.replace(url, uri)
            (folder / name).write_text(text, encoding="utf-8")
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(toolkit_cache, "CACHE_DIR_PATH", cache)
            mp.setattr(requests, "get", _no_network)
            mp.setattr(requests.Session, "request", _no_network)
            mp.setattr(urllib.request, "urlopen", _no_network)
            from dcc_json_toolkit import DccSchema
            from dcclib.validation import SchematronValidator, XsdValidator

            yield cls(
                XsdValidator.from_file(str(folder / "dcc.xsd")),
                SchematronValidator.for_dcc(),
                DccSchema(VERSION),
            )

    def problems(self, xml: bytes) -> list[str]:
        """Every XSD error and every failed Schematron assertion ([] for a valid DCC)."""
        text = xml.decode("utf-8")
        xsd = self.xsd.validate_str(text)
        sch = self.schematron.validate_str(text)
        return [f"XSD line {e.line}: {e.message}" for e in xsd.errors] + [
            f"Schematron {f.role} at {f.location}: {f.text}" for f in sch.failed_assertions
        ]

    def read(self, xml: bytes) -> dict[str, Any]:
        """The DCC as dcc-json-toolkit decodes it (numbers typed by the schema)."""
        data: dict[str, Any] = self.schema.to_dict(xml.decode("utf-8"))
        return data


def _many(node: Any) -> list[Any]:
    return node if isinstance(node, list) else [node]


def _ref(node: dict[str, Any]) -> set[str]:
    return set(_many(node.get("@refType", [])))


def _with_ref(nodes: Any, ref: str) -> list[dict[str, Any]]:
    return [n for n in _many(nodes) if ref in _ref(n)]


def _one(nodes: Any, ref: str) -> dict[str, Any]:
    found = _with_ref(nodes, ref)
    assert len(found) == 1, f"{len(found)} elements of refType {ref}"
    return found[0]


def _list(quantity: dict[str, Any]) -> dict[str, list[Any]]:
    """A quantity's realListXMLList: values, and U, k, p when stated."""
    real = quantity["si:realListXMLList"]
    out = {"values": list(real["si:valueXMLList"])}
    mu = real.get("si:measurementUncertaintyUnivariateXMLList")
    if mu is not None:
        expanded = mu["si:expandedMUXMLList"]
        out["u"] = list(expanded["si:valueExpandedMUXMLList"])
        out["k"] = list(expanded["si:coverageFactorXMLList"])
        out["p"] = list(expanded["si:coverageProbabilityXMLList"])
    return out


def read_back(data: dict[str, Any]) -> dict[str, Any]:
    """What a machine reads from a decoded DCC (see the module docstring), by refType."""
    admin = data["dcc:administrativeData"]
    result_set = _many(data["dcc:measurementResults"]["dcc:measurementResult"])[0]
    results = _many(result_set["dcc:results"]["dcc:result"])
    response = _one(results, "vib_frequencyResponse")
    quantities = _many(_many(response["dcc:data"]["dcc:list"])[0]["dcc:quantity"])
    out: dict[str, Any] = {
        "f": _list(_one(quantities, "vib_frequency"))["values"],
        "magnitude": _list(_one(quantities, "vib_sensitivityMagnitude")),
    }
    phase = _with_ref(quantities, "vib_sensitivityPhase")
    out["phase"] = _list(phase[0]) if phase else None
    deviation = _with_ref(quantities, "vib_relativeDeviation")
    out["deviation"] = _list(deviation[0]) if deviation else None
    conformity = _with_ref(results, "vib_characteristicConformity")
    out["conformity"] = None
    if conformity:
        points = _many(_many(conformity[0]["dcc:data"]["dcc:list"])[0]["dcc:quantity"])
        dev = _one(points, "vib_relativeDeviation")
        meta = _one(dev["dcc:measurementMetaData"]["dcc:metaData"], "basic_conformity")
        limits = _many(meta["dcc:data"]["dcc:quantity"])
        out["conformity"] = {
            "f": _list(_one(points, "vib_frequency"))["values"],
            "deviation": _list(dev),
            "status": list(meta["dcc:conformityXMLList"]),
            "lower": _list(_one(limits, "basic_toleranceLimitLower"))["values"],
            "upper": _list(_one(limits, "basic_toleranceLimitUpper"))["values"],
        }
    rule = _one(admin["dcc:statements"]["dcc:statement"], "basic_decisionRule")
    quantities = _many(rule["dcc:data"]["dcc:quantity"])
    rule_data = {next(iter(_ref(q))): q["si:real"]["si:value"] for q in quantities}
    out["rule"] = {"norm": list(rule["dcc:norm"]), **rule_data}
    ids = _many(admin["dcc:coreData"]["dcc:identifications"]["dcc:identification"])
    out["seal"] = _one(ids, "vib_runSeal")["dcc:value"]
    out["release"] = _many(admin["dcc:dccSoftware"]["dcc:software"])[0]["dcc:release"]
    return out


def _number(text: str) -> float:
    return float(text)


def expected(run: Path) -> dict[str, Any]:
    """The same items from the run (results.json, seal.json), printed as the certificate
    prints them (app.certificate.printed: the one rounding), the conformity mapped here on its
    own: pass, fail; inconclusive -> conditionalPass inside the tolerance, conditionalFail
    outside; the reference line and lines not stated are not listed."""
    from app.certificate.load import load_stored_run
    from app.certificate.printed import printed_lines
    from app.records.seal import read_seal

    stored = load_stored_run(run)
    lines = printed_lines(stored.results)
    raw = json.loads((run / "results.json").read_text(encoding="utf-8"))["results"]
    tolerance = raw["tolerance_percent"]
    out: dict[str, Any] = {
        "f": [_number(ln.frequency) for ln in lines],
        "magnitude": {
            "values": [_number(ln.sensitivity) for ln in lines],
            "u": [_number(ln.expanded) for ln in lines],
            "k": [_number(ln.k) for ln in lines],
            "p": [raw["coverage_probability"]] * len(lines),
        },
        "seal": read_seal(run)[1],
        "tolerance": tolerance,
    }
    conformity: dict[str, list[Any]] = {"f": [], "status": [], "deviation": [], "u": []}
    for line, printed in zip(raw["lines"], lines, strict=True):
        verdict = line["tolerance_verdict"]
        if verdict not in ("pass", "fail", "inconclusive"):
            continue
        deviation = line["deviation_percent"]
        if verdict == "inconclusive":
            verdict = "conditionalPass" if abs(deviation) <= tolerance else "conditionalFail"
        conformity["f"].append(_number(printed.frequency))
        conformity["status"].append(verdict)
        conformity["deviation"].append(_number(printed.deviation))
        conformity["u"].append(_number(printed.deviation_expanded))
    out["conformity"] = conformity
    out["phase"] = {
        "values": [_number(ln.phase) for ln in lines],
        "u": [_number(ln.phase_expanded) for ln in lines],
    }
    return out


def assert_reads_back_as_the_run(found: dict[str, Any], run: Path) -> None:
    """Every number the independent reader found equals the run's (see `expected`)."""
    want = expected(run)
    assert found["f"] == want["f"]
    for key in ("values", "u", "k", "p"):
        assert found["magnitude"][key] == want["magnitude"][key], key
    assert found["phase"] is not None
    assert found["phase"]["values"] == want["phase"]["values"]
    assert found["phase"]["u"] == want["phase"]["u"]
    assert found["seal"] == want["seal"]
    tolerance = want["tolerance"]
    assert found["rule"]["norm"] == ["ILAC-G8:09/2019"]
    assert found["rule"]["vib_guardBandFactor"] == 1.0
    assert found["rule"]["basic_toleranceLimitLower"] == -tolerance
    assert found["rule"]["basic_toleranceLimitUpper"] == tolerance
    points = want["conformity"]
    assert points["status"], "the run states no conformity: nothing to compare"
    got = found["conformity"]
    assert got["f"] == points["f"]
    assert got["status"] == points["status"]
    assert got["deviation"]["values"] == points["deviation"]
    assert got["deviation"]["u"] == points["u"]
    assert got["lower"] == [-tolerance] * len(points["f"])
    assert got["upper"] == [tolerance] * len(points["f"])
    assert all(math.isfinite(v) for v in got["deviation"]["values"])
