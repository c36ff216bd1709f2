"""`accelcal impact` (issue 27 point 1): on a records database with runs on two reference
standards it lists exactly the runs of the named one in the window, each re-analysed from its
recording with the corrected table: the new sensitivity is the old times the ratio of the
tables (hand-checked at the reference frequency), verdicts that change are named, and the
certificates of those runs are flagged under review (audited)."""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

import pytest
from sqlalchemy import select, update
from sqlalchemy.orm import Session

from app.cli import main
from app.procedure import impact
from app.procedure.run import RunRequest, execute
from app.records.db.engine import open_engine
from app.records.db.lab import Lab, RecordsError
from app.records.db.models import AuditEntry, Run
from app.records.run_folder import MANIFEST_NAME
from tests.records_db import new_records, seed_lab

pytestmark = pytest.mark.integration

ROOT = Path(__file__).resolve().parents[3]
K_160 = 1.02  # the corrected table's factor at 160 Hz (the reference frequency)
K_HIGH = 1.10  # above 1 kHz: a 10 % change of the characteristic, beyond the 5 % tolerance


def _stand_with_reference(folder: Path, identifier: str, serial: str) -> Path:
    text = (ROOT / "sim" / "stand.toml").read_text(encoding="utf-8")
    text = text.replace('id = "REF-8305-SIM"', f'id = "{identifier}"')
    text = text.replace('serial = "SIM-0001"', f'serial = "{serial}"')
    path = folder / f"stand-{serial}.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def lab_runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, Path, dict[str, str]]:
    """Three runs on reference SIM-0001 (one of them dated 2025, before the window) and one on
    SIM-0002, indexed; a certificate for each of the 2026 runs."""
    base = tmp_path_factory.mktemp("impact")
    runs = base / "runs"
    other = _stand_with_reference(base, "REF-OTHER", "SIM-0002")
    made: dict[str, str] = {}
    for label, serial, stand in (
        ("old", "SN-A", None),
        ("a", "SN-A", None),
        ("a2", "SN-C", None),
        ("b", "SN-B", other),
    ):
        finished = execute(
            RunRequest(
                dut="piezo",
                dut_id=serial,
                periods=4,
                tolerance_percent=5.0,
                out=runs,
                stand_file=stand,
            )
        )
        made[label] = str(finished.record.run_id)
    url = new_records(base / "records.sqlite")
    engine = open_engine(url)
    lab = seed_lab(
        Lab(engine, actor="tester"),
        {"SN-A": "Alpha GmbH", "SN-C": "Alpha GmbH", "SN-B": "Beta Ltd"},
        nominal_sensitivity=10.0,
        frequency_min_hz=10,
        addresses={"Alpha GmbH": "1 Main St"},
    )
    report = lab.import_runs(runs)
    assert len(report.imported) == 4, report
    with Session(engine) as s, s.begin():  # the first run dates from before the window
        s.execute(
            update(Run)
            .where(Run.run_id == made["old"])
            .values(started_utc=datetime(2025, 3, 1, tzinfo=UTC))
        )
    for label in ("old", "a", "b"):
        lab.issue_certificate(run_id=made[label], prepared_by="P. Rep", approved_by="A. Pro")
    return url, runs, made


def _corrected_table(run_folder: Path, path: Path) -> None:
    """The stored table of the run with every sensitivity times K_160 up to 160 Hz... and
    K_HIGH from 1 kHz (the hand-checked ratio at the reference frequency is K_160)."""
    chain = json.loads((run_folder / "results.json").read_text())["reference_chain"]
    lines = ["frequency_hz,sensitivity_mv_per_ms2,relative_expanded_uncertainty_percent,phase_deg"]
    for f, s, p in zip(
        chain["frequencies_hz"], chain["sensitivity_mv_per_ms2"], chain["phase_deg"], strict=True
    ):
        k = K_HIGH if f >= 1000 else K_160
        lines.append(f"{f!r},{s * k!r},0.5,{p!r}")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _stored(runs: Path, run_id: str) -> dict:
    return json.loads((runs / run_id / "results.json").read_text())


def test_impact_lists_exactly_the_runs_of_the_reference_in_the_window(
    lab_runs, tmp_path: Path, capsys
) -> None:
    url, runs, made = lab_runs
    table = tmp_path / "corrected.csv"
    _corrected_table(runs / made["a"], table)
    out = tmp_path / "report"
    code = main(
        [
            "impact",
            "SIM-0001",
            "--table",
            str(table),
            "--since",
            "2026-01-01",
            "--db",
            url,
            "--out",
            str(out),
            "--workers",
            "2",
        ]
    )
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "impact: 3/3 runs" in captured.err  # the progress line: count of the window's runs
    rows = list(csv.DictReader((out / "impact-SIM-0001.csv").open()))
    assert sorted(r["run_id"] for r in rows) == sorted([made["a"], made["a2"]])
    for row in rows:
        stored = _stored(runs, row["run_id"])["results"]["reference"]
        old, new = (
            float(row["old_sensitivity_mv_per_ms2"]),
            float(row["new_sensitivity_mv_per_ms2"]),
        )
        assert old == pytest.approx(stored["sensitivity_mv_per_ms2"], rel=1e-9)
        assert new == pytest.approx(K_160 * stored["sensitivity_mv_per_ms2"], rel=1e-9)
        u = stored["expanded_uncertainty_mv_per_ms2"]
        assert float(row["change_in_u"]) == pytest.approx((K_160 - 1) * old / u, abs=2e-3)
        # the characteristic moved by K_HIGH / K_160 - 1 = 7.8 % > 5 %: the verdict fails
        assert row["old_verdict"] == "PASS" and row["new_verdict"] == "FAIL", row
        assert row["verdict_changed"] == "yes"
    assert made["b"] not in captured.out and made["old"] not in captured.out
    assert (out / "impact-SIM-0001.pdf").read_bytes().startswith(b"%PDF")
    notice = (out / "notice-Alpha_GmbH.txt").read_text()
    assert "DRAFT" in notice and "SN-A" in notice and "SN-C" in notice
    assert not (out / "notice-Beta_Ltd.txt").exists()
    engine = open_engine(url)
    lab = Lab(engine)
    reviews = lab.reviews(open_only=True)
    numbers = {c.number for c in lab.register() if c.run.run_id == made["a"]}
    assert {r.number for r in reviews} == numbers and len(numbers) == 1  # old and b: not flagged
    assert "to amend or confirm" in reviews[0].reason and "PASS -> FAIL" in reviews[0].reason
    with Session(engine) as s:
        audited = s.scalars(
            select(AuditEntry).where(AuditEntry.table_name == "certificate_reviews")
        ).all()
    assert len(audited) == 1
    # a second assessment opens no second review of the same subject
    assert main(["impact", "SIM-0001", "--table", str(table), "--since", "2026-01-01",
                 "--db", url, "--out", str(tmp_path / "again"), "--workers", "1"]) == 0  # fmt: skip
    assert len(Lab(engine).reviews()) == 1


def test_a_changed_run_folder_is_reported_not_checked(lab_runs, tmp_path: Path) -> None:
    """A folder whose manifest is not the one indexed is named, never re-analysed."""
    url, runs, made = lab_runs
    copy = tmp_path / "copy"
    shutil.copytree(runs / made["a"], copy)
    copy.chmod(0o755)
    (copy / MANIFEST_NAME).chmod(0o644)
    (copy / MANIFEST_NAME).write_text((copy / MANIFEST_NAME).read_text() + " ")
    lab = Lab(open_engine(url))
    indexed = next(r for r in lab.runs_between(None, None) if r.run_id == made["a"])
    task = impact.Task(
        made["a"], str(copy), indexed.manifest_sha256, indexed.started_utc, "SN-A", None, ()
    )
    table = tmp_path / "t.csv"
    _corrected_table(runs / made["a"], table)
    result = impact.reanalyse(task, "SIM-0001", impact.read_table(table))
    assert result.uses_reference and result.problem is not None
    assert "differs from the one indexed" in result.problem


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("160,10,0.005\n100,10,0.005\n", "line 2: frequencies must increase"),
        ("160,-1,0.005\n", "line 1: frequency and sensitivity must be > 0"),
        ("160,abc,0.005\n", "line 1: not a number"),
        ("160,10\n", "line 1: expected 3 or 4 columns"),
        ("# nothing\n", "holds no table rows"),
    ],
)
def test_a_bad_table_is_refused_by_line(tmp_path: Path, text: str, message: str, capsys) -> None:
    table = tmp_path / "t.csv"
    table.write_text(text)
    assert main(["impact", "X", "--table", str(table), "--db", "sqlite://"]) == 2
    assert message in capsys.readouterr().err


def test_refs_add_and_impact_read_one_table_file_alike(lab_runs, tmp_path: Path, capsys) -> None:
    """Issue 33 point 6: `impact --table` read the uncertainty column as a fraction where `refs
    add` reads percent. The same file through both commands: both read 2.0 as 2 % (0.02), and
    a table whose header calls the column a fraction is refused by both, naming the column."""
    url, runs, made = lab_runs
    table = tmp_path / "corrected.csv"
    _corrected_table(runs / made["a"], table)
    table.write_text(table.read_text().replace(",0.5,", ",2.0,"), encoding="utf-8")
    add = ["refs", "add", "REF-NEW", "--model", "8305", "--serial", "SIM-NEW", "--certificate",
           "C-1", "--calibrated", "2026-01-01", "--due", "2027-01-01", "--db", url]  # fmt: skip
    assert main([*add, "--table", str(table)]) == 0, capsys.readouterr().err
    (stored,) = [r for r in Lab(open_engine(url), actor="t").references() if r.serial == "SIM-NEW"]
    assert {p.relative_expanded_uncertainty for p in stored.points} == {0.02}
    out = tmp_path / "report"
    argv = ["impact", "SIM-0001", "--table", str(table), "--db", url, "--out", str(out)]
    assert main([*argv, "--no-flag", "--workers", "1"]) == 0, capsys.readouterr().err
    assert set(impact.read_table(table).relative_expanded_uncertainty) == {0.02}
    fraction = tmp_path / "fraction.csv"
    text = table.read_text().replace("uncertainty_percent", "uncertainty")
    fraction.write_text(text, encoding="utf-8")
    capsys.readouterr()
    assert main([*add[:2], "REF-F", *add[3:], "--table", str(fraction)]) == 2
    assert "column 'relative_expanded_uncertainty' does not say its unit" in capsys.readouterr().err
    assert main(["impact", "SIM-0001", "--table", str(fraction), "--db", url]) == 2
    assert "column 'relative_expanded_uncertainty' does not say its unit" in capsys.readouterr().err


def test_names_written_as_formulas_go_into_the_impact_csv_as_text(
    lab_runs, tmp_path: Path, capsys
) -> None:
    """Issue 33 point 6: a customer or DUT named like a spreadsheet formula went raw into the
    impact CSV (a spreadsheet would run it). Now such a cell starts with an apostrophe, and
    the signed numbers beside it stay numbers."""
    from app.records.db.models import Customer

    url, runs, made = lab_runs
    copy = tmp_path / "records.sqlite"
    source = url.removeprefix("sqlite:///")
    for suffix in ("", "-wal", "-shm"):  # the records in WAL mode: the log holds the rows
        if Path(source + suffix).exists():
            shutil.copyfile(source + suffix, str(copy) + suffix)
    url = f"sqlite:///{copy}"
    evil_owner, evil_dut = '=HYPERLINK("http://x.example/?q=1","Open")', "@SUM(1+1)"
    with Session(open_engine(url)) as s, s.begin():
        s.execute(update(Customer).where(Customer.name == "Alpha GmbH").values(name=evil_owner))
        s.execute(update(Run).where(Run.run_id == made["a"]).values(dut_id=evil_dut))
    table = tmp_path / "corrected.csv"
    _corrected_table(runs / made["a"], table)
    out = tmp_path / "report"
    argv = ["impact", "SIM-0001", "--table", str(table), "--db", url, "--out", str(out)]
    assert main([*argv, "--no-flag", "--since", "2026-01-01"]) == 0, capsys.readouterr().err
    rows = list(csv.DictReader((out / "impact-SIM-0001.csv").open(encoding="utf-8")))
    assert rows, capsys.readouterr().out[:600]
    mine = next(r for r in rows if r["run_id"] == made["a"])
    assert mine["owner"] == "'" + evil_owner and mine["dut_id"] == "'" + evil_dut
    for row in rows:
        for value in row.values():
            assert not value.startswith(("=", "@", "\t", "\r")), value
        assert float(row["change_in_u"]) == pytest.approx(float(row["change_in_u"]))  # a number


def _children(pid: int) -> set[int]:
    """The processes whose parent is `pid` running its command line (its forked workers)."""
    found = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
                forked = b"impact" in (entry / "cmdline").read_bytes()  # a worker, not a helper
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid and forked:
                found.add(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc (Linux)")
def test_impact_workers_end_when_their_parent_is_killed(lab_runs, tmp_path: Path) -> None:
    """Issue 33 point 6: `impact` workers outlived a SIGKILL of their parent (6 left, 130 MB
    each). The parent is killed while its workers re-analyse; every worker is gone soon after
    (the kernel's parent-death signal; a watch thread elsewhere)."""
    url, runs, made = lab_runs
    table = tmp_path / "corrected.csv"
    _corrected_table(runs / made["a"], table)
    argv = ["impact", "SIM-0001", "--table", str(table), "--db", url, "--no-flag"]
    command = [sys.executable, "-m", "app", *argv, "--out", str(tmp_path / "r"), "--workers", "2"]
    parent = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    workers: set[int] = set()
    deadline = time.monotonic() + 120
    while not workers and parent.poll() is None and time.monotonic() < deadline:
        workers = _children(parent.pid)
        time.sleep(0.02)
    assert workers, f"no worker seen (exit {parent.poll()}): {parent.stderr.read()!r}"
    parent.kill()
    parent.wait()
    left = set(workers)
    deadline = time.monotonic() + 10
    while left and time.monotonic() < deadline:
        left = {pid for pid in left if _alive(pid)}
        time.sleep(0.05)
    for pid in left:  # a failing run leaves none behind
        os.kill(pid, signal.SIGKILL)
    assert not left, f"workers {sorted(left)} outlived their parent"


def test_progress_line_counts_and_time_left() -> None:
    assert impact.progress_line(1, 4, 2.0) == "impact: 1/4 runs, 2 s, about 6 s left"
    assert impact.progress_line(4, 4, 8.0) == "impact: 4/4 runs, 8 s"


def test_a_review_is_closed_as_amended_or_confirmed_once(lab_runs) -> None:
    url, _, made = lab_runs
    lab = Lab(open_engine(url), actor="qm")
    number = next(c.number for c in lab.register() if c.run.run_id == made["b"])
    assert lab.open_review(number, subject="impact of reference X", reason="check it")
    assert not lab.open_review(number, subject="impact of reference X", reason="again")
    with pytest.raises(RecordsError, match="outcome: must be one of amended, confirmed"):
        lab.close_review(number, subject="impact of reference X", outcome="ignored", reason="r")
    lab.close_review(number, subject="impact of reference X", outcome="confirmed", reason="stands")
    closed = [r for r in lab.reviews() if r.number == number]
    assert [(r.outcome, r.closed_utc is not None) for r in closed] == [("confirmed", True)]
    with pytest.raises(RecordsError, match="has no open review"):
        lab.close_review(number, subject="impact of reference X", outcome="amended", reason="r")
    with pytest.raises(RecordsError, match="number: no certificate"):
        lab.open_review("NOPE-1", subject="s", reason="r")


def test_the_window_starts_at_the_references_calibration_by_default(
    lab_runs, tmp_path: Path, capsys
) -> None:
    """No --since: the window opens at the calibration date of the reference on record (its
    last good calibration), so the 2025 run stays out; --no-flag opens no review."""
    from datetime import date

    url, runs, made = lab_runs
    lab = Lab(open_engine(url))
    if not any(r.identifier == "REF-8305-SIM" for r in lab.references()):
        lab.add_reference(
            "REF-8305-SIM",
            model="8305",
            serial="SIM-0001",
            certificate_number="C-1",
            calibration_date=date(2026, 1, 1),
            due_date=date(2027, 1, 1),
            table=[(160.0, 1.0, 0.005, 0.0)],
        )
    before = len(lab.reviews())
    table = tmp_path / "corrected.csv"
    _corrected_table(runs / made["a"], table)
    out = tmp_path / "report"
    argv = ["impact", "REF-8305-SIM", "--table", str(table), "--db", url, "--out", str(out)]
    assert main([*argv, "--workers", "1", "--no-flag"]) == 0
    captured = capsys.readouterr()
    assert "Window: 2026-01-01 to now; 3 indexed run(s) checked, 2 used this reference" in (
        captured.out
    )
    assert made["old"] not in captured.out and made["a"] in captured.out
    assert len(Lab(open_engine(url)).reviews()) == before
