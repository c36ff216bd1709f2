"""RunStart (config.json) and SweepSummary (sweep-<id>.json): typed, and byte-identical to the
files written before they existed."""

from __future__ import annotations

import json

import pytest

from app.records.run_start import RunStart, RunStartError
from app.records.sweep_summary import SweepSummary, SweepSummaryError

# config.json as app/procedure wrote it before RunStart: json.dumps(..., indent=2, default=str)
OLD_CONFIG = {
    "stand": {
        "laboratory": {"name": "Lab", "country": "PL"},
        "reference": {"id": "REF-1", "serial": "7"},
        "certificate": {"mounting": "stud"},
    },
    "stand_source": "stand.toml",
    "plan": {"sample_rate_hz": 6000.0, "period_samples": 12000, "lines": []},
    "settings": {"periods": 8, "tolerance_percent": None, "fade_out_s": 0.5},
    "identity": {"dut": {"id": "SN-7"}, "level_ms2": 10.0},
}
OLD_SWEEP = {
    "status": "complete",
    "levels_ms2": [3.0, 6.0],
    "run_ids": ["a", "b"],
    "abort_reason": None,
    "frequencies_hz": [160.0, 1000.0],
    "sensitivity_mv_per_ms2": [[10.0, 10.5], [10.1, 10.4]],
    "linearity_percent": [0.5, 0.48],
    "reference_frequency_hz": 160.0,
    "reference_linearity_percent": 0.5,
    "worst_linearity_percent": 0.5,
    "worst_linearity_frequency_hz": 160.0,
}


def test_config_json_reads_typed_and_writes_the_same_bytes(tmp_path):
    text = json.dumps(OLD_CONFIG, indent=2, default=str)
    (tmp_path / "config.json").write_text(text, encoding="utf-8")
    start = RunStart.read(tmp_path)
    assert start.laboratory == {"name": "Lab", "country": "PL"}
    assert start.reference["id"] == "REF-1"
    assert start.certificate_defaults() == {"mounting": "stud"}
    assert start.settings["fade_out_s"] == 0.5 and start.identity["dut"] == {"id": "SN-7"}
    assert start.to_json() == text


def test_an_older_config_json_loads_and_keeps_what_it_does_not_know(tmp_path):
    older = {"stand": {"laboratory": {"name": "Lab"}}, "plan": {}, "note": "kept"}
    start = RunStart.from_json(json.dumps(older))
    assert start.laboratory == {"name": "Lab"} and start.reference == {}
    assert start.stand_source is None and start.settings == {} and start.extra == {"note": "kept"}
    assert RunStart.read(tmp_path) == RunStart()  # no config.json: nothing stored
    assert RunStart().stand is None  # the record's stand is used then (app.certificate.dcc)


@pytest.mark.parametrize(
    ("text", "reason"),
    [("{", "not JSON"), ("[]", "not a JSON object"), ('{"stand": 3}', "stand: not a table")],
)
def test_a_broken_config_json_is_refused_by_name(tmp_path, text, reason):
    (tmp_path / "config.json").write_text(text)
    with pytest.raises(RunStartError, match=f"config.json: {reason}"):
        RunStart.read(tmp_path)


def test_sweep_summary_reads_typed_and_writes_the_same_bytes(tmp_path):
    path = tmp_path / "sweep-x.json"
    path.write_text(json.dumps(OLD_SWEEP, indent=2), encoding="utf-8")
    sweep = SweepSummary.read(path)
    assert sweep.complete and sweep.run_ids == ("a", "b")
    assert sweep.table is not None and sweep.table.sensitivity_mv_per_ms2[1] == (10.1, 10.4)
    assert sweep.to_json() == path.read_text(encoding="utf-8")
    head = SweepSummary.read(path, with_table=False)
    assert head.table is None and head.complete  # the file has its table, not read yet


def test_an_aborted_or_broken_sweep_summary(tmp_path):
    aborted = {"status": "aborted", "levels_ms2": [3.0], "run_ids": ["a"], "abort_reason": "x"}
    assert not SweepSummary.from_dict(aborted).complete
    assert SweepSummary.from_dict(aborted).to_dict() == aborted
    path = tmp_path / "s.json"
    path.write_text(json.dumps({**OLD_SWEEP, "linearity_percent": "high"}))
    with pytest.raises(SweepSummaryError, match=r"s\.json: malformed sweep summary"):
        SweepSummary.read(path)
    path.write_text("not json")
    with pytest.raises(SweepSummaryError, match=r"s\.json: cannot be read"):
        SweepSummary.read(path)
