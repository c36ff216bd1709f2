"""What a certificate states of the reference standard's DCC (issue 35 point 4): when the run
took its reference's table from a DCC read into the records (`refs add --dcc`), the PDF and the
DCC name that DCC by its uniqueIdentifier, calibrating laboratory and SHA-256, as the run's
results.json holds them (stand.reference dcc_identifier, dcc_laboratory, dcc_sha256).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping
from html import escape
from typing import Any

DCC_NS = "https://ptb.de/dcc"
LABEL = "Its DCC"
NAME = "Reference standard's DCC"
SHA_NAME = "Reference standard's DCC (SHA-256)"
REF_DCC = "vib_referenceDcc"
REF_DCC_SHA256 = "vib_referenceDccSha256"


def reference_dcc(reference: Mapping[str, Any]) -> tuple[str, str, str] | None:
    """(uniqueIdentifier, laboratory, SHA-256) of the run's reference DCC, None without one."""
    identifier = str(reference.get("dcc_identifier") or "")
    sha256 = str(reference.get("dcc_sha256") or "")
    if not (identifier and sha256):
        return None
    return identifier, str(reference.get("dcc_laboratory") or ""), sha256


def pdf_rows(reference: Mapping[str, Any]) -> list[tuple[str, str]]:
    """The PDF's rows (label, reportlab markup) naming the reference DCC; [] without one."""
    found = reference_dcc(reference)
    if found is None:
        return []
    identifier, laboratory, sha256 = found
    issuer = f" of {escape(laboratory)}" if laboratory else ""
    # the hash on a line of its own, small enough never to be split (a reader copies it whole)
    return [(LABEL, f'DCC {escape(identifier)}{issuer}<br/><font size="7">SHA-256 {sha256}</font>')]


def dcc_identifications(identifications: ET.Element, reference: Mapping[str, Any]) -> None:
    """Add to the measuring equipment's dcc:identifications the reference DCC's
    uniqueIdentifier (issuer: the calibration laboratory) and SHA-256, each with its refType."""
    found = reference_dcc(reference)
    if found is None:
        return
    identifier, laboratory, sha256 = found
    for issuer, value, name, ref_type in (
        (
            "calibrationLaboratory",
            identifier,
            f"{NAME}, {laboratory}" if laboratory else NAME,
            REF_DCC,
        ),
        ("other", sha256, SHA_NAME, REF_DCC_SHA256),
    ):
        element = ET.SubElement(identifications, f"{{{DCC_NS}}}identification", refType=ref_type)
        ET.SubElement(element, f"{{{DCC_NS}}}issuer").text = issuer
        ET.SubElement(element, f"{{{DCC_NS}}}value").text = value
        text = ET.SubElement(element, f"{{{DCC_NS}}}name")
        ET.SubElement(text, f"{{{DCC_NS}}}content", lang="en").text = name
