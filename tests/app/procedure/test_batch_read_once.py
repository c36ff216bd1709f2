"""A batch's members after the first (issue 36 point 7's speed): each member's recording is read
once after the run, and its results are bit for bit those of analysing its stored file."""

from __future__ import annotations

from pathlib import Path

import pytest

from app.io import hdf5
from app.procedure import batch as batch_module
from app.procedure import batch_files
from app.procedure.analysis import analyze
from app.procedure.batch import MemberChoice, execute_batch
from app.procedure.request import RunRequest
from app.stand import config as stand_config

pytestmark = pytest.mark.integration

STAND = Path(__file__).parents[3] / "sim" / "stand-fixture4.toml"


def test_a_member_is_read_once_and_its_results_are_its_files(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    reads: list[Path] = []

    def counted(path, *args, **kwargs):  # type: ignore[no-untyped-def]
        if not kwargs.get("stored"):  # a whole read (stored=True reads a slice at a time)
            reads.append(Path(path))
        return hdf5.read_recording(path, *args, **kwargs)

    monkeypatch.setattr(batch_files, "read_recording", counted)
    monkeypatch.setattr(batch_module, "read_recording", counted)
    request = RunRequest(
        stand_file=STAND, out=tmp_path / "runs", seed=5, periods=3, stored_response=False
    )
    choices = [MemberChoice("A", "SN-A"), MemberChoice("B", "SN-B"), MemberChoice("C", "SN-C")]
    finished = execute_batch(request, choices, config=stand_config.load(STAND))
    others = [one for _, one in finished.members[1:]]
    paths = [finished.folder.parent / str(one.record.run_id) / "recording.h5" for one in others]
    assert sorted(reads) == sorted(paths)  # once each, by own_budget; the analysis reads none
    monkeypatch.undo()
    for one, path in zip(others, paths, strict=True):
        assert one.results is not None
        again = analyze(hdf5.read_recording(path), estimator=str(one.results.estimator)).results
        for mine, theirs in zip(one.results.lines, again.lines, strict=True):
            assert mine.sensitivity_mv_per_ms2 == theirs.sensitivity_mv_per_ms2
            assert mine.expanded_uncertainty_mv_per_ms2 == theirs.expanded_uncertainty_mv_per_ms2
            assert mine.phase_deg == theirs.phase_deg
            assert mine.phase_expanded_uncertainty_deg == theirs.phase_expanded_uncertainty_deg
