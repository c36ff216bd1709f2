"""What the records' register says of a certificate `accelcal verify` examines (issue 35
point 1): the number is in the register, the file is the one issued (its SHA-256 against the
register's), the certificate is still in force (not withdrawn, not replaced by an amendment),
and an amendment states what the register holds (the number it replaces and the reason).

The records are checked (app.records.db.gate) before they are read; the register, not the file,
says whether a certificate is in force: a withdrawn certificate verifies as withdrawn however
intact its signature.
"""

from __future__ import annotations

import hashlib

from app.certificate.readback import PrintedItems
from app.records.db.lab import Lab

CHECK = "in force in the records' register"


class RecordsUnavailable(Exception):
    """The records at the URL cannot be opened (missing, no schema, unreachable): the register
    is not consulted, and the report says so beside its checks."""


def register_findings(
    data: bytes, printed: PrintedItems, url: str, of_dcc: bool = False
) -> tuple[bool, str]:
    """(ok, detail) of the certificate whose PDF bytes (`of_dcc`: DCC bytes) are `data` and
    whose printed items are `printed` against the register at `url`. RecordsUnavailable
    when the records cannot be opened; ChainBroken (a Refusal) when they fail their check."""
    from app.records.db.engine import DatabaseError, open_engine
    from app.records.db.gate import quick_check

    try:
        engine = open_engine(url)
    except DatabaseError as exc:
        raise RecordsUnavailable(str(exc)) from None
    try:
        quick_check(engine)  # verified before it is read
        return _findings(data, printed, Lab(engine), of_dcc)
    finally:
        engine.dispose()


def _findings(
    data: bytes, printed: PrintedItems, lab: Lab, of_dcc: bool = False
) -> tuple[bool, str]:
    """`register_findings` on records already opened and checked."""
    number = str(printed.number)
    if not number:
        return False, "the certificate prints no number"
    row = lab.certificate(number)
    if row is None:
        return False, f"the register has no certificate {number}"
    digest = hashlib.sha256(data).hexdigest()
    issued_hash = row.dcc_sha256 if of_dcc else row.sha256
    if of_dcc and not issued_hash:
        return False, f"the register holds no DCC of certificate {number}"
    if issued_hash and issued_hash != digest:
        return False, (
            f"this file is not the certificate {number} the register holds (SHA-256 "
            f"{digest[:16]}..., issued {issued_hash[:16]}...)"
        )
    replaced = lab.certificate(row.replaces) if row.replaces else None
    reason = str(replaced.reason or "") if replaced is not None else ""  # kept on the old row
    problems = _amendment_differences(printed, row.replaces or "", reason)
    if problems:
        return False, "; ".join(problems)
    if row.state == "withdrawn":
        return False, f"certificate {number} is WITHDRAWN: {row.reason or 'no reason recorded'}"
    if row.state == "replaced":
        successor = next((r.number for r in lab.register() if r.replaces == number), "")
        return False, (
            f"certificate {number} is REPLACED by {successor or 'an amendment'} "
            f"({row.reason or 'no reason recorded'}): use that one"
        )
    issued = f"issued {row.issued_utc:%Y-%m-%d}"
    unhashed = "" if row.sha256 else " (entered before the register kept hashes: file not compared)"
    return True, f"certificate {number} {issued}, in force{unhashed}"


def _amendment_differences(printed: PrintedItems, replaces: str, reason: str) -> list[str]:
    """Where what the certificate prints of an amendment differs from the register."""
    out = []
    if str(printed.replaces) != replaces:
        out.append(
            f"it prints that it replaces {str(printed.replaces) or 'nothing'}, the register "
            f"{replaces or 'nothing'}"
        )
    if replaces and " ".join(str(printed.amendment_reason).split()) != " ".join(reason.split()):
        out.append(
            f"it prints the reason {str(printed.amendment_reason)!r}, the register {reason!r}"
        )
    return out
