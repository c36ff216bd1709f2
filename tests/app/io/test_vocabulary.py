"""The stored words as StrEnums: each spelled once, written as the same text as before."""

from __future__ import annotations

import json

import h5py
import pytest

from app.io.hdf5 import RecordingWriter, read_recording, recording_status
from app.io.vocabulary import Mode, RunStatus
from app.procedure.modes import MODE_MULTISINE, MODE_STEPPED_SINE, MODES
from app.records import run_folder
from app.records.run_folder import FolderState
from app.records.run_record import RunRecord
from dsp.calibration import ReferenceChain
from dsp.multisine import make_plan
from dsp.uncertainty import Budget
from tests.synthetic import lowpass_response, make_recording

# the text stored files hold, as written before the enums (results.json, HDF5, database)
STORED_STATUSES = {"complete", "aborted", "incomplete"}
STORED_MODES = {"multisine", "stepped-sine"}
FOLDER_STATES = {"complete", "aborted", "running", "interrupted", "modified", "unsupported"}


def test_the_enums_spell_the_stored_text() -> None:
    assert {s.value for s in RunStatus} == STORED_STATUSES
    assert {m.value for m in Mode} == STORED_MODES
    assert {s.value for s in FolderState} == FOLDER_STATES
    assert FolderState.COMPLETE == RunStatus.COMPLETE == "complete"
    assert json.dumps({"status": RunStatus.ABORTED, "mode": Mode.STEPPED_SINE}) == (
        '{"status": "aborted", "mode": "stepped-sine"}'
    )
    assert f"{RunStatus.INCOMPLETE} recording" == "incomplete recording"


def test_the_old_names_are_the_members() -> None:
    assert MODES == ("multisine", "stepped-sine") and all(type(m) is str for m in MODES)
    assert MODE_MULTISINE is Mode.MULTISINE and MODE_STEPPED_SINE is Mode.STEPPED_SINE
    assert run_folder.STATUS_COMPLETE is FolderState.COMPLETE
    assert run_folder.STATUS_INTERRUPTED is FolderState.INTERRUPTED


def test_a_record_round_trips_its_status_as_text() -> None:
    record = RunRecord(run_id="r1", status=RunStatus.ABORTED, abort_reason="test")
    text = json.dumps(record.to_dict())
    assert '"status": "aborted"' in text and '"mode": "multisine"' in text
    back = RunRecord.from_dict(json.loads(text))
    assert back.status == RunStatus.ABORTED and not back.complete


@pytest.mark.parametrize(
    ("mark", "expected"),
    [("complete", "complete"), (b"aborted", "aborted"), (None, "incomplete"), ("x", "incomplete")],
)
def test_recording_status_reads_the_mark(mark: object, expected: str) -> None:
    status = recording_status(mark)
    assert type(status) is RunStatus and status.value == expected


def test_the_recording_stores_plain_text(tmp_path) -> None:
    plan = make_plan([100.0, 200.0], 1000.0, 10, 1.0, 100.0, phases_rad=[0.0, 0.0])
    rec = make_recording(plan, lowpass_response(), periods=2)
    path = tmp_path / "r.h5"
    with RecordingWriter(path, plan, ReferenceChain.flat(1.0), Budget(())) as writer:
        writer.append(rec.reference_v, rec.dut_v)
        writer.set_mode(Mode.MULTISINE)
        assert writer.set_status(RunStatus.ABORTED, "test")
    with h5py.File(path, "r") as f:
        assert f.attrs["status"] == "aborted" and f.attrs["mode"] == "multisine"
        assert isinstance(f.attrs["status"], str)
    assert read_recording(path).status == RunStatus.ABORTED
