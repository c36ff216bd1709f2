"""The reference standard of a run as the records give it (issue 24): on record (by the stand
file's [reference] id or serial) or refused, in date or refused, its table the one the run
uses (a differing stand-file table refused), its calibration uncertainty in the budget, and
every override granted (typed, in results.json and in the records' audit trail).

Units: frequencies in Hz, sensitivities in mV/(m/s^2), phases in degrees, relative
uncertainties as fractions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, date, datetime
from typing import TYPE_CHECKING, Any

from app.errors import Refusal
from app.records.run_record import Override, OverrideKind
from dsp.uncertainty import Budget

if TYPE_CHECKING:
    from app.records.db.references import ReferenceTable
    from app.stand.config import StandConfig

__all__ = [
    "ReferenceRefusal",
    "ResolvedReference",
    "reference_budget",
    "reference_from_records",
    "resolve_reference",
    "simulators_own",
    "table_phases",
]


class ReferenceRefusal(Refusal):
    """The stand's reference standard cannot be used as the records hold it; `overridable`:
    an override reason would let the run go on (not on record, past its due date)."""

    def __init__(self, message: str, *, overridable: bool) -> None:
        super().__init__(message)
        self.overridable = overridable


@dataclass(frozen=True)
class ResolvedReference:
    """The reference standard as the records give it: its table (None: the stand file's or
    the simulated stand's own), the overrides granted, notes to show."""

    table: ReferenceTable | None = None
    overrides: tuple[Override, ...] = ()
    notes: tuple[str, ...] = ()


REFERENCE_COMPONENT = "reference standard calibration"  # the stand file's, replaced
SIMULATED_BACKEND = "sim"  # [daq] backend of a simulated stand: its reference is the simulator's


def reference_budget(budget: Budget, table: ReferenceTable) -> Budget:
    """`budget` with its magnitude component named "reference standard calibration" (the stand
    file's estimate) replaced by the records' table: its relative expanded uncertainties
    (fractions, normal, k = 2 as certificates state them) in frequency bands, each point's
    from that point up to just below the next, the larger of the two (lines in between are
    interpolated from both), the first also below the table and the last above it; bands of
    equal value merged. Without such a component the records' are added."""
    from dsp.annex_a import ComponentKind
    from dsp.uncertainty import Component, Distribution, Quantity

    REFERENCE_KIND = ComponentKind.REFERENCE_CALIBRATION

    freqs, values = table.frequencies_hz, table.relative_expanded_uncertainty
    bands: list[tuple[float | None, float | None, float]] = []
    for i, frequency in enumerate(freqs):
        last = i == len(freqs) - 1
        value = values[i] if last else max(values[i], values[i + 1])
        low = None if i == 0 else frequency
        high = None if last else math.nextafter(freqs[i + 1], 0.0)
        if i == 0 and len(freqs) > 1 and values[0] != value:  # below the table: the first's
            bands.append((None, math.nextafter(frequency, 0.0), values[0]))
            low = frequency
        if bands and bands[-1][2] == value:
            bands[-1] = (bands[-1][0], high, value)
        else:
            bands.append((low, high, value))
    note = f"records: certificate {table.certificate_number} of {table.identifier}"
    replaced = [
        c
        for c in budget.components
        if c.name == REFERENCE_COMPONENT and c.quantity is Quantity.MAGNITUDE
    ]
    # the Annex A component(s) it states: the stand file's entry's, else the reference's own
    kind = replaced[0].kind if replaced and replaced[0].kind else (REFERENCE_KIND,)
    records = tuple(
        Component(
            REFERENCE_COMPONENT if len(bands) == 1 else f"{REFERENCE_COMPONENT} (band {n})",
            value,
            Distribution.NORMAL,
            coverage_factor=2.0,
            quantity=Quantity.MAGNITUDE,
            min_frequency_hz=low,
            max_frequency_hz=high,
            note=note,
            kind=kind,
        )
        for n, (low, high, value) in enumerate(bands, 1)
    )
    kept = tuple(c for c in budget.components if c not in replaced)
    return Budget((*records, *kept))


def table_phases(table: ReferenceTable) -> tuple[float, ...]:
    """The table's phases (deg); a certificate stating none: 0 at every frequency (as a stand
    file without phase_deg); ReferenceRefusal when only some rows state one."""
    given = [p for p in table.phase_deg if p is not None]
    if not given:
        return (0.0,) * len(table.frequencies_hz)
    if len(given) != len(table.phase_deg):
        raise ReferenceRefusal(
            f"reference: the records' table of {table.identifier} states a phase on some rows "
            "only; enter it again with a phase on every row or on none",
            overridable=False,
        )
    return tuple(given)


def _same_table(config: StandConfig, table: ReferenceTable) -> bool:
    """Whether the stand file's [reference] table is the records' (within 1e-9 relative)."""
    ref = config.reference

    def close(a: tuple[float, ...], b: tuple[float, ...], absolute: float) -> bool:
        return len(a) == len(b) and all(
            math.isclose(x, y, rel_tol=1e-9, abs_tol=absolute) for x, y in zip(a, b, strict=True)
        )

    return (
        close(ref.frequencies_hz, table.frequencies_hz, 0.0)
        and close(ref.sensitivity_mv_per_ms2, table.sensitivity_mv_per_ms2, 0.0)
        and close(ref.phase_deg, table_phases(table), 1e-9)
    )


def simulators_own(config: StandConfig) -> bool:
    """Whether the stand's reference standard is the simulator's own: a simulated stand
    (`daq.backend = "sim"`) whose stand file gives its reference no table, so the simulator
    draws it (the built-in stand's REF-8305-SIM). Such a reference cannot be a laboratory's
    standard; a stand file that states its reference's table (a lab's stand, or a test of the
    rule) is held to the rule like a real stand."""
    return config.backend == SIMULATED_BACKEND and not config.reference.frequencies_hz


def resolve_reference(
    config: StandConfig,
    table: ReferenceTable | None,
    *,
    today: date,
    override_reason: str | None,
    who: str,
    now_utc: datetime,
) -> ResolvedReference:
    """The reference standard of `config` given what the records hold of it (`table`; None:
    not on record) on `today`: refused (ReferenceRefusal naming it) when not on record or past its
    due date, unless `override_reason` is given (an Override by `who` at `now_utc`), and when
    the stand file carries a table that differs from the records' (no override: two sources
    for one reference are never right). The simulator's own reference (`simulators_own`) not
    on record is used as such (a note, no override): it cannot be a laboratory's standard, so
    it has no certificate to record; on record, the rule applies to it as to any. A real
    stand's reference is always held to the rule (docs/records.md)."""
    ref = config.reference
    reason = (override_reason or "").strip() or None
    when = now_utc.isoformat(timespec="seconds")
    if table is None and simulators_own(config):
        note = (
            f"reference standard {ref.id} (serial {ref.serial}) of {config.source}: the "
            "simulator's own (simulated stand, not a laboratory's standard), its table drawn "
            "by the simulator; not looked up in the records"
        )
        return ResolvedReference(None, (), (note,))
    if table is None:
        what = (
            f"reference standard {ref.id} (serial {ref.serial}) of {config.source} is not in "
            "the records"
        )
        if reason is None:
            raise ReferenceRefusal(
                f"reference: {what}; add it (accelcal refs add, with its calibration table) or "
                "give an override reason (--reference-override; it is printed on the "
                "certificate)",
                overridable=True,
            )
        override = Override(OverrideKind.UNRECORDED_REFERENCE, who, reason, when, what)
        note = f"{what}; used under the override: {reason} (the stand file's table)"
        return ResolvedReference(None, (override,), (note,))
    name = table.identifier
    if ref.frequencies_hz and not _same_table(config, table):
        raise ReferenceRefusal(
            f"reference: the [reference] table of {config.source} differs from the records' "
            f"table of {name} (certificate {table.certificate_number}); remove the table from "
            "the stand file (the records' is used) or correct whichever is wrong",
            overridable=False,
        )
    table_phases(table)  # refuses a table with a phase on some rows only
    if table.due_date >= today:
        note = (
            f"reference standard {name}: certificate {table.certificate_number}, due "
            f"{table.due_date}; its table from the records"
            + (
                ""
                if table.dcc is None
                else f", read from its DCC {table.dcc.unique_identifier} (SHA-256 "
                f"{table.dcc.sha256})"
            )
        )
        return ResolvedReference(table, (), (note,))
    what = f"reference standard {name} was due for calibration on {table.due_date}"
    if reason is None:
        raise ReferenceRefusal(
            f"reference: {name} was due for calibration on {table.due_date}; recalibrate it, "
            "or give an override reason (--reference-override; it is printed on the "
            "certificate)",
            overridable=True,
        )
    override = Override(OverrideKind.EXPIRED_REFERENCE, who, reason, when, what)
    note = (
        f"reference standard {name} was due on {table.due_date}; used under the override: {reason}"
    )
    return ResolvedReference(table, (override,), (note,))


def open_records(lab: Any, db: str | None) -> tuple[Any, str | None]:
    """The records (`lab`: a face's open app.records.db.lab.Lab, else those of the URL `db` or
    $ACCELCAL_DB) and None, or None and why they cannot be reached."""
    if lab is not None:
        return lab, None
    from app.records.db.engine import DatabaseError, open_engine
    from app.records.db.lab import Lab

    try:
        return Lab(open_engine(db)), None
    except DatabaseError as exc:
        return None, str(exc)


def reference_from_records(
    config: StandConfig,
    lab: Any,
    *,
    override_reason: str | None,
    who: str,
    today: date | None = None,
) -> ResolvedReference:
    """`resolve_reference` on the records `lab` (an app.records.db.lab.Lab) at this moment
    (`today`: the face's date, else the UTC date)."""
    now = datetime.now(UTC)
    table = lab.reference_table(config.reference.id, config.reference.serial)
    return resolve_reference(
        config,
        table,
        today=today or now.date(),
        override_reason=override_reason,
        who=who,
        now_utc=now,
    )


def audit_overrides(lab: Any, config: StandConfig, overrides: tuple[Override, ...]) -> None:
    """Enter the overrides in the records' audit trail (`lab`), keyed by the stand's reference
    standard's id."""
    for override in overrides:
        lab.record_override(override, config.reference.id)
