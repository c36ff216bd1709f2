"""Stating a calibration: the PDF certificate and its DCC, made from a stored run only
(SPEC.md section 10; ISO/IEC 17025 clause 7.8).

    info            the items beyond the run, their defaults and checks (CertificateInfo)
    load            the stored run (StoredRun) and its sweep summary, verified
    printed         one line as printed (PrintedLine): the one rounding for PDF, DCC, verify
    text            every sentence the certificate states
    pdf, pdf_charts drawing the PDF
    dcc             the Digital Calibration Certificate (XML)
    issuing         the issue transaction with the runs root's JSON register (no records)
    register_issue  the issue transaction with the records database's register
    sign            PAdES signing and `accelcal verify`

Re-exported here: what the faces call.
"""

from __future__ import annotations

from app.certificate.info import CertificateError, CertificateInfo
from app.certificate.issuing import build, dcc_path, issue
from app.certificate.load import StoredRun, load_stored_run
from app.records.register import Issued

__all__ = [
    "CertificateError",
    "CertificateInfo",
    "Issued",
    "StoredRun",
    "build",
    "dcc_path",
    "issue",
    "load_stored_run",
]
