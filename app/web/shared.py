"""A sensor's runs shared with other DUTs (issue 36: several DUTs in one excitation), for the
staff's sensor page: per run its batch, the sensor's own position on the fixture, and every
other member's serial and position. Read from the run index (runs.batch_id, migration 0015)
and, for the positions, from the sensor's own run folder's config.json batch link when the web
view can read it (else the position is blank: the serials still come from the records). Staff
only: the customer portal never calls this (a shared run's other members may belong to other
customers)."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.records.db.models import Run, Sensor
from app.records.run_start import RunStart

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SharedMember:
    """Another DUT of a shared run: its serial and fixture position ("" when not known)."""

    serial: str
    position: str


@dataclass(frozen=True)
class SharedRun:
    """One run the sensor shared: the batch, its own run and position, the other members."""

    batch_id: str
    run_id: str
    started_utc: datetime
    status: str
    position: str
    others: tuple[SharedMember, ...]


def _positions(folder: str) -> dict[str, str]:
    """Run id -> position of every member named by a member run folder's batch link ({}
    when the folder is not readable here or names no batch)."""
    try:
        link = RunStart.read(Path(folder)).batch
    except Exception as exc:  # the folder on another machine, moved, unreadable: not fatal
        log.info("web view: batch positions of %s not read: %s", folder, exc)
        return {}
    return {} if link is None else {m.run_id: m.position for m in link.members}


def shared_runs(session: Session, serial: str) -> list[SharedRun]:
    """The runs of sensor `serial` that were one DUT of several, newest first."""
    own = (
        session.execute(
            select(Run)
            .join(Sensor, Run.sensor_id == Sensor.id)
            .where(Sensor.serial == serial, Run.batch_id.is_not(None))
            .order_by(Run.started_utc.desc(), Run.id.desc())
        )
        .scalars()
        .all()
    )
    if not own:
        return []
    batches = {r.batch_id for r in own}
    members: dict[str, list[tuple[str, str]]] = {}
    for batch_id, run_id, dut_id in session.execute(
        select(Run.batch_id, Run.run_id, Run.dut_id)
        .where(Run.batch_id.in_(batches))
        .order_by(Run.dut_id)
    ):
        members.setdefault(str(batch_id), []).append((str(run_id), str(dut_id)))
    out = []
    for run in own:
        positions = _positions(run.folder)
        others = tuple(
            SharedMember(dut_id, positions.get(run_id, ""))
            for run_id, dut_id in members.get(str(run.batch_id), [])
            if run_id != run.run_id and dut_id != serial  # a triaxial's channels: its own
        )
        started = run.started_utc
        out.append(
            SharedRun(
                str(run.batch_id),
                run.run_id,
                started if started.tzinfo else started.replace(tzinfo=UTC),
                run.status,
                positions.get(run.run_id, ""),
                tuple(sorted(others, key=lambda m: (m.position, m.serial))),
            )
        )
    return out
