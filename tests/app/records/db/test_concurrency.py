"""Two stands issuing certificates at once against one database: no gap, no duplicate."""

from __future__ import annotations

import subprocess
import sys
from datetime import UTC, datetime

from sqlalchemy import Engine, select
from sqlalchemy.orm import Session

from app.records.db.lab import Lab
from app.records.db.models import Certificate, Run, Sensor, Stand
from tests.records_db import seed_lab

WORKER = """
import sys
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
lab = Lab(open_engine(sys.argv[1]), actor=sys.argv[2])
for i in range(50):  # one certificate per run: each stand certifies runs of its own
    lab.issue_certificate(run_id=f"{sys.argv[2]}-{i}", prepared_by=sys.argv[2], approved_by="QM")
"""


def test_two_processes_issue_100_distinct_numbers_without_a_gap(engine: Engine) -> None:
    seed_lab(Lab(engine, actor="setup"), {"SN-1": "ACME Ltd"})
    with Session(engine) as s:
        stand = Stand(stand_file_sha256="b" * 64, name="stand")
        sensor = s.scalar(select(Sensor))
        for n, name in enumerate(f"stand-{x}-{i}" for x in "AB" for i in range(50)):
            s.add(
                Run(
                    run_id=name,
                    manifest_sha256=f"{n:064x}",
                    folder=f"/{name}",
                    status="complete",
                    started_utc=datetime(2026, 11, 23, tzinfo=UTC),
                    dut_id="SN-1",
                    stand=stand,
                    sensor=sensor,
                )
            )
        s.commit()
    url = engine.url.render_as_string(hide_password=False)
    workers = [
        subprocess.Popen([sys.executable, "-c", WORKER, url, name], stderr=subprocess.PIPE)
        for name in ("stand-A", "stand-B")
    ]
    for worker in workers:
        _, err = worker.communicate(timeout=240)
        assert worker.returncode == 0, err.decode()
    with Session(engine) as s:
        rows = s.execute(select(Certificate.sequence, Certificate.prepared_by)).all()
    assert sorted(seq for seq, _ in rows) == list(range(1, 101))
    assert {who for _, who in rows} == {"stand-A", "stand-B"}
