"""`accelcal refs add ID --dcc FILE --due DATE`: a reference standard added from its
calibrating laboratory's DCC (app.io.reference_dcc): the DCC read and refused (exit 2, naming
the element) before the records are opened; its table, identity, dates and item taken, options
given checked against it; the DCC kept in the records with its SHA-256. Units as the records':
Hz, mV/(m/s^2), relative U at k = 2, degrees. `accelcal refs dcc ID --out FILE` writes the DCC
kept back out, byte for byte (its SHA-256 checked)."""

from __future__ import annotations

import argparse
import logging
from collections.abc import Callable
from typing import TYPE_CHECKING

from app.records.db.errors import RecordsInputError

if TYPE_CHECKING:
    from app.io.reference_dcc import ReferenceDcc
    from app.records.db.lab import Lab

log = logging.getLogger(__name__)


class DccOptionError(RecordsInputError):
    """An option of `refs add --dcc` that contradicts the DCC; the message names both."""


def checked_fields(args: argparse.Namespace, dcc: ReferenceDcc) -> dict[str, object]:
    """The reference's model, serial, certificate number and calibration date: the DCC's,
    an option given for the serial, certificate or date refused where it differs (the wrong
    DCC for this standard); --model names the model as the lab does (default the DCC's)."""
    serial = dcc.serial or (args.serial or "")
    if not serial:
        raise DccOptionError(
            "--dcc: the DCC's item states no serial number "
            "(dcc:items/dcc:item/dcc:identifications); give --serial"
        )
    for option, given, stated in (
        ("--serial", args.serial, dcc.serial or None),
        ("--certificate", args.certificate, dcc.unique_identifier),
        ("--calibrated", args.calibrated, dcc.calibration_date),
    ):
        if given is not None and stated is not None and given != stated:
            raise DccOptionError(
                f"{option}: {given} differs from the DCC's {stated} ({args.dcc}); leave it out "
                "to take the DCC's, or read in the DCC of this reference standard"
            )
    model = args.model or dcc.model or ""
    if not model:
        raise DccOptionError("--dcc: the DCC's item states no model (dcc:model); give --model")
    return {
        "model": model,
        "serial": serial,
        "certificate_number": dcc.unique_identifier,
        "calibration_date": dcc.calibration_date,
    }


def describe(dcc: ReferenceDcc) -> list[str]:
    """What was read, for the terminal: identity, item, table, units, signature, SHA-256."""
    first, last = dcc.points[0].frequency_hz, dcc.points[-1].frequency_hz
    lines = [
        f"DCC {dcc.unique_identifier} of {dcc.laboratory}, calibrated {dcc.begin_date} to "
        f"{dcc.end_date}",
        f"item: {dcc.manufacturer} {dcc.model}, serial {dcc.serial or 'not stated'}".replace(
            "  ", " "
        ),
        f"table: {len(dcc.points)} frequencies, {first:g} Hz to {last:g} Hz, sensitivity in "
        f"{dcc.sensitivity_unit}, phase "
        + ("stated" if dcc.points[0].phase_deg is not None else "not stated"),
    ]
    if dcc.charge:
        lines.append(
            "a charge sensitivity: kept in mV/(m/s^2) at 1 mV/pC (the stand file's [reference] "
            "gain is the charge amplifier's)"
        )
    factors = sorted({p.coverage_factor for p in dcc.points}, key=lambda k: (k is None, k))
    if factors != [2.0]:
        shown = ", ".join("a coverage interval" if k is None else f"k = {k:g}" for k in factors)
        lines.append(f"U stated with {shown}: kept as the relative U at k = 2")
    lines += [f"signature: {dcc.signature.line()}", f"SHA-256: {dcc.sha256}"]
    return lines


def add_from_dcc(args: argparse.Namespace, open_lab: Callable[[], Lab]) -> int:
    """Read the DCC (refused before the records are opened), add the reference, print."""
    from app.io.reference_dcc import read_reference_dcc

    dcc = read_reference_dcc(args.dcc, "--dcc", args.dcc_certificate)
    fields = checked_fields(args, dcc)
    lab = open_lab()
    row = lab.add_reference(
        args.identifier,
        due_date=args.due,
        table=dcc.table(),
        dcc=dcc,
        **fields,  # type: ignore[arg-type]
    )
    log.info(
        "reference %s added from DCC %s (%s)", row.identifier, dcc.unique_identifier, dcc.sha256
    )
    print(
        f"reference {row.identifier} added from its DCC ({len(dcc.points)} table rows, due "
        f"{row.due_date})"
    )
    for line in describe(dcc):
        print(f"  {line}")
    return 0


def write_kept(args: argparse.Namespace, lab: Lab) -> int:
    """Write reference `args.identifier`'s DCC in force to `args.out` (never overwritten)."""
    from app.files import FileExistsRefusal, TargetRefusal, write_new

    kept = lab.reference_dcc(args.identifier)
    if kept is None:
        raise DccOptionError(
            f"reference {args.identifier}: no DCC in force (its table was not read from one, or "
            "a recalibration replaced it)"
        )
    try:
        write_new(args.out, kept.content)
    except (FileExistsRefusal, TargetRefusal) as exc:
        raise DccOptionError(f"--out: {exc}") from None
    print(
        f"{args.out}: DCC {kept.identity.unique_identifier} of {kept.identity.laboratory} "
        f"({kept.file_name}, read in {kept.added_utc:%Y-%m-%d}), SHA-256 {kept.identity.sha256}"
    )
    return 0
