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

CHECK = "in force in the records' register"


class RecordsUnavailable(Exception):
    """The records at the URL cannot be opened (missing, no schema, unreachable): the register
    is not consulted, and the report says so beside its checks."""


def register_findings(data: bytes, printed: PrintedItems, url: str) -> tuple[bool, str]:
    """(ok, detail) of the certificate whose PDF bytes are `data` and whose printed items are
    `printed` against the register at `url`. RecordsUnavailable when the records cannot be
    opened; ChainBroken (a Refusal) when they fail their check."""
    from app.records.db.engine import DatabaseError, open_engine
    from app.records.db.gate import quick_check
    from app.records.db.lab import Lab

    try:
        engine = open_engine(url)
    except DatabaseError as exc:
        raise RecordsUnavailable(str(exc)) from None
    try:
        quick_check(engine)  # verified before it is read
    finally:
        engine.dispose()
    number = str(printed.number)
    if not number:
        return False, "the certificate prints no number"
    row = Lab(open_engine(url)).certificate(number)
    if row is None:
        return False, f"the register has no certificate {number}"
    digest = hashlib.sha256(data).hexdigest()
    if row.sha256 and row.sha256 != digest:
        return False, (
            f"this file is not the certificate {number} the register holds (SHA-256 "
            f"{digest[:16]}..., issued {row.sha256[:16]}...)"
        )
    problems = _amendment_differences(printed, row.replaces or "", _reason_of(row, url))
    if problems:
        return False, "; ".join(problems)
    if row.state == "withdrawn":
        return False, f"certificate {number} is WITHDRAWN: {row.reason or 'no reason recorded'}"
    if row.state == "replaced":
        successor = _successor(url, number)
        return False, (
            f"certificate {number} is REPLACED by {successor or 'an amendment'} "
            f"({row.reason or 'no reason recorded'}): use that one"
        )
    issued = f"issued {row.issued_utc:%Y-%m-%d}"
    unhashed = "" if row.sha256 else " (entered before the register kept hashes: file not compared)"
    return True, f"certificate {number} {issued}, in force{unhashed}"


def _reason_of(row: object, url: str) -> str:
    """The reason an amendment gives: the register keeps it on the replaced row."""
    replaces = getattr(row, "replaces", None)
    if not replaces:
        return ""
    from app.records.db.engine import open_engine
    from app.records.db.lab import Lab

    old = Lab(open_engine(url)).certificate(replaces)
    return str(old.reason or "") if old is not None else ""


def _successor(url: str, number: str) -> str:
    """The number of the certificate that replaces `number` ("" when none is found)."""
    from app.records.db.engine import open_engine
    from app.records.db.lab import Lab

    for row in Lab(open_engine(url)).register():
        if row.replaces == number:
            return str(row.number)
    return ""


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
