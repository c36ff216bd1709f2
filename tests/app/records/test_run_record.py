"""The typed run record (app.records.run_record): today's results.json reads, newer schemas
refused."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from app.records.run_folder import (
    STATUS_UNSUPPORTED,
    RunFolder,
    inspect_run,
    load_run,
    write_manifest,
)
from app.records.run_record import (
    SCHEMA_VERSION,
    DutIdentity,
    RunRecord,
    RunRecordError,
    UnsupportedSchemaError,
)

DATA = Path(__file__).parent / "data"
# written by `accelcal run --sim --periods 3 --seed 1` before results.json had a schema_version
UNVERSIONED = DATA / "results-unversioned.json"


def test_a_results_json_written_before_schema_version_still_reads():
    text = UNVERSIONED.read_text()
    record = RunRecord.from_json(text)
    raw = json.loads(text)
    assert "schema_version" not in raw
    assert record.schema_version == SCHEMA_VERSION
    assert record.run_id == raw["run_id"] and record.status == "complete" and record.complete
    assert record.mode == "multisine" and record.periods_read == raw["periods_read"]
    assert record.excitation_time_s == raw["excitation_time_s"] and record.final_output_v == 0.0
    assert record.dut == DutIdentity("piezo", None, None) and record.level_ms2 == 5.0
    assert record.stand.description.startswith("simulated stand")
    assert record.stand.reference["id"] == "REF-8305-SIM"
    assert record.verdict == "PASS" and record.verdict_reasons == tuple(raw["verdict_reasons"])
    assert record.raw_data_sha256 == raw["raw_data_sha256"]
    results = record.results_object()
    assert results is not None and results.periods == 3 and len(results.lines) == 25
    assert record.extra == {}


def test_the_record_round_trips_and_keeps_every_key_it_was_given():
    raw = json.loads(UNVERSIONED.read_text())
    record = RunRecord.from_json(UNVERSIONED.read_text())
    again = json.loads(record.to_json())
    assert again.pop("schema_version") == SCHEMA_VERSION
    assert again == raw
    assert RunRecord.from_json(record.to_json()) == record


def test_a_newer_schema_version_is_refused_by_name(tmp_path):
    raw = json.loads(UNVERSIONED.read_text())
    raw["schema_version"] = SCHEMA_VERSION + 1
    with pytest.raises(UnsupportedSchemaError, match=rf"schema_version {SCHEMA_VERSION + 1}"):
        RunRecord.from_dict(raw)
    folder = tmp_path / "run"  # a stored run of a newer accelcal: verified, then refused
    folder.mkdir()
    (folder / "results.json").write_text(json.dumps(raw))
    write_manifest(folder)
    check = inspect_run(folder)
    assert check.state == STATUS_UNSUPPORTED and "newer" in check.problems[0]
    with pytest.raises(UnsupportedSchemaError, match="schema_version"):
        load_run(folder)


@pytest.mark.parametrize(
    ("document", "message"),
    [
        ([], "not a JSON object"),
        ({"run_id": "x"}, "no 'status'"),
        ({"status": "complete", "schema_version": "1"}, "not valid"),
    ],
)
def test_malformed_records_are_refused_with_the_reason(document, message):
    with pytest.raises(RunRecordError, match=message):
        RunRecord.from_dict(document)


def test_a_run_folder_writes_the_typed_record(tmp_path):
    folder = RunFolder.create(tmp_path, "typed")
    record = RunRecord(run_id=folder.run_id, status="aborted", abort_reason="test")
    written = folder.finish(record, None)
    assert written.raw_data_sha256 is None and written.results is None
    stored = json.loads((folder.path / "results.json").read_text())
    assert stored["schema_version"] == SCHEMA_VERSION and stored["abort_reason"] == "test"
    assert load_run(folder.path) == written
