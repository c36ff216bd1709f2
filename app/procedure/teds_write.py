"""Writing a calibration to the DUT's TEDS (the use case of `accelcal teds write`): the new TEDS
a stored, verified, complete run gives (its sensitivity at the reference frequency and its
date), whether the sensor on the port is the run's DUT, and the write itself, with an override
logged and, with records in use, audited before anything is written.

The port and the codec live below (`app.stand.teds`, `hardware.teds`); this module needs the
run's record (`app.records.run_record.RunRecord`) and the records, so it sits above both."""

from __future__ import annotations

import logging
import re
from collections.abc import Callable
from dataclasses import dataclass
from datetime import date

from app.records.run_record import RunRecord
from app.stand.teds import TedsPort, sensor_named, write_checked
from hardware.teds import Teds, TedsError, decode

log = logging.getLogger(__name__)

OVERRIDE_WHAT = "teds write: different sensor"


def calibrated_teds(current: tuple[int, ...], record: RunRecord, initials: str) -> Teds:
    """The TEDS `current` with the sensitivity (mV/(m/s^2) at the reference frequency) and the
    date of a complete run's record."""
    teds = decode(current)
    if teds.accelerometer is None:
        raise TedsError(f"TEDS: template {teds.template_id} is no accelerometer template (25)")
    reference = record.reference_result if record.complete else None
    if reference is None or reference.sensitivity_mv_per_ms2 is None:
        raise TedsError("run: only a complete run's result is written to a TEDS")
    when = date.fromisoformat(record.finished_utc[:10])
    new = teds.accelerometer.with_sensitivity(reference.sensitivity_mv_per_ms2, when, initials)
    return Teds(teds.basic, teds.selector, teds.template_id, new, teds.trailing_bits)


def identity_mismatch(teds: Teds, record: RunRecord, expected: str | None = None) -> str | None:
    """Why the sensor whose TEDS this is is not the run's DUT (None: it is). `expected`: the
    TEDS identity the records keep for the run's sensor ('manufacturer/model/version/serial':
    serial and model compared); else the run's DUT serial must be the TEDS serial (the same
    number, or TEDS-<identity> as `run --teds` names a DUT without records)."""
    basic = teds.basic
    if expected:
        if basic.identity != expected.strip():
            return (
                f"the TEDS names {sensor_named(teds)}, the run's sensor has TEDS identity "
                f"{expected.strip()} in the records"
            )
        return None
    serial = ((record.dut.id if record.dut else None) or "").strip()
    if serial == f"TEDS-{basic.identity.replace('/', '-')}" or serial == str(basic.serial_number):
        return None
    digits = re.search(r"(\d+)$", serial)
    if digits and int(digits.group(1)) == basic.serial_number:
        return None
    return f"the TEDS names {sensor_named(teds)}, the run's DUT is {serial or 'not named'}"


@dataclass(frozen=True)
class TedsWrite:
    """A run's result about to be written to the TEDS on a port: what is there, what will be,
    and why the sensor is not the run's DUT (`mismatch`, None when it is)."""

    port: TedsPort
    record: RunRecord
    present: Teds
    new: Teds
    mismatch: str | None

    def refusal(self, override: str | None) -> str | None:
        """Why the write is refused before anyone is asked (None: it may go ahead): a sensor
        that is not the run's DUT and no override reason."""
        if self.mismatch is None or (override or "").strip():
            return None
        return (
            f"teds write: {self.mismatch}; not written (a different sensor, if meant: "
            "--yes-different-sensor REASON)"
        )

    @property
    def sensor(self) -> str:
        """The sensor on the port, for people (serial, model, manufacturer, identity)."""
        return sensor_named(self.present)

    @property
    def change(self) -> str:
        """The change in words: sensitivity in mV/(m/s^2) old -> new, the calibration date."""
        old, new = self.present.accelerometer, self.new.accelerometer
        assert new is not None  # calibrated_teds refuses a TEDS without the template
        return (
            f"sensitivity {old.sensitivity_mv_per_ms2 if old else float('nan'):.5g} -> "
            f"{new.sensitivity_mv_per_ms2:.5g} mV/(m/s^2), calibration date "
            f"{new.calibration_date} (run {self.record.run_id})"
        )


def plan_write(port: TedsPort, record: RunRecord, initials: str, db: str | None) -> TedsWrite:
    """Read the port's TEDS and work out the write of `record`'s result (nothing is written).
    `db`: the records URL given (--db), else the records in use, whose TEDS identity of the
    run's sensor decides whether the sensor is the run's DUT. TedsError: no accelerometer
    TEDS, or no complete run."""
    current = port.read()
    new = calibrated_teds(current, record, initials)
    present = decode(current)
    mismatch = identity_mismatch(present, record, records_identity(record, db))
    return TedsWrite(port, record, present, new, mismatch)


def write(
    plan: TedsWrite,
    override: str | None,
    db: str | None,
    announce: Callable[[str], None] = lambda line: None,
) -> None:
    """Write the planned TEDS and read it back. A sensor that is not the run's DUT needs an
    override reason, which is logged, handed to `announce` and, with records in use, audited,
    all before the write. TedsError: no reason for a different sensor, or the read-back
    differs."""
    refused = plan.refusal(override)
    if refused is not None:
        raise TedsError(refused)
    if plan.mismatch is not None:
        announce(record_override(plan, (override or "").strip(), db))  # never after the write
    write_checked(plan.port, plan.new)


def records_identity(record: RunRecord, db: str | None) -> str | None:
    """The TEDS identity the records keep for the run's sensor (None: no records in use, the
    sensor is not on record or has none)."""
    from app.records.db.engine import records_url

    url = records_url(db)
    serial = (record.dut.id if record.dut else None) or ""
    if url is None or not serial:
        return None
    from app.records.db.engine import open_engine
    from app.records.db.lab import Lab
    from app.records.db.store import RecordsError

    try:
        return Lab(open_engine(url)).sensor(serial).teds_identity or None
    except RecordsError:
        return None


def record_override(plan: TedsWrite, reason: str, db: str | None) -> str:
    """The override logged (the run folder is sealed: its log is never appended to) and, with
    records in use, entered in their audit trail; returns the line logged."""
    line = (
        f"teds write to a different sensor for run {plan.record.run_id}: {plan.mismatch}; "
        f"override: {reason}"
    )
    log.warning("%s", line)
    from app.records.db.engine import records_url

    url = records_url(db)
    if url is not None:
        from app.records.db.engine import open_engine
        from app.records.db.lab import Lab

        Lab(open_engine(url)).note_override(
            str(plan.record.run_id), OVERRIDE_WHAT, f"{plan.mismatch}; reason: {reason}"
        )
    return line
