"""Issue 31 point 4, a first use that works: records are created only by `accelcal db upgrade`
(opening them, the GUI, a run or a records query never creates them), and the simulated stand
runs alike without and with records, its own reference standard used as such, while a lab's
reference (a real stand's, or a stand file stating its table) is still held to the rule."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from app.cli import main
from app.records.db.engine import RecordsMissing, open_engine, records_url
from app.stand import config as stand_config
from tests.lab_stand import lab_stand_file

RUN = ["run", "--sim", "--periods", "3", "--seed", "1"]


@pytest.fixture
def data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A fresh data directory and no $ACCELCAL_DB: the default records file is its
    records.sqlite, which does not exist yet."""
    folder = tmp_path / "data"
    monkeypatch.setenv("ACCELCAL_DATA_DIR", str(folder))
    monkeypatch.delenv("ACCELCAL_DB", raising=False)
    return folder


@pytest.mark.integration  # records databases
def test_opening_or_querying_the_records_never_creates_them(
    data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    default = data / "records.sqlite"
    with pytest.raises(RecordsMissing, match=r"does not exist; `accelcal db upgrade` creates it"):
        open_engine()
    explicit = tmp_path / "lab.sqlite"
    with pytest.raises(RecordsMissing, match=r"lab\.sqlite: does not exist"):
        open_engine(f"sqlite:///{explicit}")
    assert not default.exists() and not explicit.exists()
    for argv in (["due"], ["customers", "add", "ACME Ltd"], ["register", "list"]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert "accelcal db upgrade" in err and "Traceback" not in err
    assert not default.exists() and records_url() is None  # still no records in use
    assert main(["db", "upgrade"]) == 0  # the one step that creates them
    assert default.is_file() and records_url() == f"sqlite:///{default}"
    assert main(["customers", "add", "ACME Ltd"]) == 0
    engine = open_engine(f"sqlite:///{explicit}", create=True)  # the tests' own way
    engine.dispose()
    assert explicit.is_file()


def test_the_window_without_records_says_how_to_create_them_and_creates_nothing(
    data: Path, qtbot, tmp_path: Path
) -> None:
    from app.gui.main_window import MainWindow

    window = MainWindow(out=tmp_path / "runs", paced=False)
    qtbot.addWidget(window)
    window.records.wait()
    assert window.records.lab is None
    for status in (window.sensors_tab.status.text(), window.register_tab.status.text()):
        assert "does not exist; `accelcal db upgrade` creates it" in status
    assert not (data / "records.sqlite").exists()


def test_the_simulators_own_reference_is_used_as_such_and_a_labs_is_held_to_the_rule(
    tmp_path: Path,
) -> None:
    from datetime import UTC, datetime

    from app.procedure.reference import ReferenceRefusal, resolve_reference, simulators_own

    now = datetime(2026, 11, 27, 12, 0, tzinfo=UTC)

    def resolve(config: stand_config.StandConfig):  # type: ignore[no-untyped-def]
        return resolve_reference(
            config, None, today=now.date(), override_reason=None, who="t", now_utc=now
        )

    built_in = stand_config.load(None)
    assert simulators_own(built_in)
    resolved = resolve(built_in)
    assert resolved.overrides == () and resolved.table is None
    assert "not looked up in the records" in resolved.notes[0]
    real = replace(built_in, backend="nidaqmx")  # a real stand: held to the rule
    lab = stand_config.load(lab_stand_file(tmp_path))  # simulated, its reference a lab's
    for config in (real, lab):
        assert not simulators_own(config)
        with pytest.raises(ReferenceRefusal, match="is not in the records") as refused:
            resolve(config)
        assert refused.value.overridable


@pytest.mark.integration
def test_the_simulated_stand_runs_without_and_with_records(
    data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "runs"
    assert main([*RUN, "--out", str(out)]) == 0  # no records in use
    assert "the simulator's own" not in capsys.readouterr().err
    assert not (data / "records.sqlite").exists()
    assert main(["db", "upgrade"]) == 0
    capsys.readouterr()
    assert main([*RUN, "--out", str(out)]) == 0  # records in use: the same run goes
    err = capsys.readouterr().err
    assert "REF-8305-SIM (serial SIM-0001) of built-in simulated stand: the simulator's own" in err
    assert len([f for f in out.iterdir() if f.is_dir()]) == 2
    lab = ["run", "--stand", str(lab_stand_file(tmp_path)), *RUN[2:]]
    assert main([*lab, "--out", str(out)]) == 2  # a lab's reference: on record or refused
    assert "is not in the records" in capsys.readouterr().err
