"""A stored recording analysed a batch of periods at a time (issue 34 point 4): the same results
as the whole recording in memory, for every estimator and for runs of earlier versions; the
same refusals (sample checks scanned in blocks, a file that cannot be read); and traced memory
that does not grow with the number of periods."""

from __future__ import annotations

import dataclasses
import shutil
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from app.io import hdf5_stream
from app.io.hdf5 import RecordingError, read_recording, write_recording
from app.io.hdf5_stream import StoredSignal
from app.procedure.analysis import analyze, analyze_chains, read_for_analysis
from dsp.multisine import make_plan
from tests.synthetic import lowpass_response, make_recording

LEGACY = Path(__file__).resolve().parents[2] / "data" / "legacy" / "runs"
LEGACY_RUN = LEGACY / "20261125T061413Z-LEG-1-2d8db0"
RELATIVE = 1e-12


def _numbers_equal(a: object, b: object, where: str = "results") -> None:
    """Every number of two result dicts equal to RELATIVE (NaN where NaN), texts equal."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), where
        for key in a:
            _numbers_equal(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, list | tuple):
        assert isinstance(b, list | tuple) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _numbers_equal(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        if np.isnan(a):
            assert np.isnan(b), where
        else:
            assert b == pytest.approx(a, rel=RELATIVE, abs=0.0), where
    else:
        assert a == b, where


@pytest.fixture(scope="module")
def recording_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """40 analysed periods after 2 settle periods (three batches of iter_batches), with noise."""
    plan = make_plan([10.0, 40.0, 160.0, 630.0], 6000, 12000, 5.0, 160.0)
    rec = make_recording(
        plan, lowpass_response(), periods=42, reference_noise_v=1e-5, dut_noise_v=1e-4, seed=3
    )
    rec = dataclasses.replace(rec, settle_periods=2)
    path = tmp_path_factory.mktemp("stream") / "rec.h5"
    write_recording(path, rec)
    return path


@pytest.mark.parametrize(
    ("estimator", "segments"),
    [("periodic", None), ("h1", None), ("seed", None), ("lpm", None), ("seed", 5)],
)
def test_stored_and_in_memory_analyses_agree(recording_file: Path, estimator, segments) -> None:
    stored = read_for_analysis(recording_file)
    assert isinstance(stored.reference_v, StoredSignal)  # the analysis reads the file
    whole = read_recording(recording_file)
    assert isinstance(whole.reference_v, np.ndarray)
    a = analyze(stored, estimator=estimator, segments=segments).results.to_dict()
    b = analyze(whole, estimator=estimator, segments=segments).results.to_dict()
    _numbers_equal(b, a)


def test_a_run_of_an_earlier_version_reanalyses_the_same(tmp_path: Path) -> None:
    folder = tmp_path / LEGACY_RUN.name
    shutil.copytree(LEGACY_RUN, folder)
    stored = read_for_analysis(folder)  # the manifest and hashes verified first
    whole = dataclasses.replace(read_recording(folder / "recording.h5"), status=stored.status)
    for estimator in ("periodic", "h1", "seed"):  # its drive has a fade inside: no lpm
        a = analyze(stored, estimator=estimator).results.to_dict()
        b = analyze(whole, estimator=estimator).results.to_dict()
        _numbers_equal(b, a, estimator)


def test_a_changed_recording_in_a_run_folder_is_still_refused(tmp_path: Path, capsys) -> None:
    folder = tmp_path / LEGACY_RUN.name
    shutil.copytree(LEGACY_RUN, folder)
    with open(folder / "recording.h5", "r+b") as f:  # one byte of the samples
        f.seek(-4096, 2)
        byte = f.read(1)
        f.seek(-4096, 2)
        f.write(bytes([byte[0] ^ 1]))
    assert main(["analyze", str(folder)]) == 2
    assert "hash mismatch" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: np.where(np.arange(d.size) == 70_001, np.nan, d), "first NaN at sample 70001"),
        (lambda d: np.where(np.arange(d.size) >= 50_000, np.inf, d), "first inf at sample 50000"),
        (lambda d: np.zeros_like(d), "flat at 0 V: dead channel"),
        # a flat top of 6 samples across the boundary of two blocks (BLOCK_SAMPLES 1000 below)
        (lambda d: np.where(np.abs(np.arange(d.size) - 999.5) < 3, 9.0, d), "6 consecutive"),
        # the largest value in a run of 4 and once more in another block: no run of 5 ...
        (lambda d: np.where(np.isin(np.arange(d.size), [10, 11, 12, 13, 5000]), 9.0, d), None),
        # ... and a larger maximum later restarts the count: its run of 5 is clipping
        (
            lambda d: np.where(
                np.isin(np.arange(d.size), [1, 2, 3, 4, 5, 6, 9995, 9996, 9997, 9998, 9999]),
                np.where(np.arange(d.size) < 100, 8.0, 9.5),
                d,
            ),
            "5 consecutive samples at 9.5",
        ),
    ],
)
def test_the_block_scan_states_what_the_whole_array_check_states(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, change, message
) -> None:
    plan = make_plan([10.0, 40.0, 160.0, 630.0], 6000, 12000, 5.0, 160.0)
    rec = make_recording(plan, lowpass_response(), periods=8, dut_noise_v=1e-4)
    rec = dataclasses.replace(rec, dut_v=change(rec.dut_v.copy()), ranges_v={})
    path = tmp_path / "bad.h5"
    write_recording(path, rec)
    monkeypatch.setattr(hdf5_stream, "BLOCK_SAMPLES", 1000)
    outcomes = []
    for stored in (False, True):
        try:
            read_recording(path, stored=stored)
            outcomes.append(None)
        except RecordingError as exc:
            outcomes.append(str(exc))
    assert outcomes[0] == outcomes[1]  # the same statement, word for word
    if message is None:
        assert outcomes[0] is None
    else:
        assert outcomes[0] is not None and message in outcomes[0]


def test_a_recording_that_cannot_be_read_mid_analysis_is_refused_by_name(
    recording_file: Path, tmp_path: Path, capsys
) -> None:
    path = tmp_path / "gone.h5"
    shutil.copy(recording_file, path)
    stored = read_for_analysis(path)
    path.write_bytes(b"not hdf5 any more")  # replaced after it was checked
    with pytest.raises(RecordingError, match=r"gone.h5: /signals/reference: cannot be read"):
        analyze(stored)
    cut = tmp_path / "cut.h5"
    data = recording_file.read_bytes()
    cut.write_bytes(data[: len(data) // 2])  # a truncated file: exit 2, named
    assert main(["analyze", str(cut)]) == 2
    err = capsys.readouterr().err
    assert "cut.h5" in err and "Traceback" not in err


def _traced_peak(path: Path, estimator: str) -> int:
    """Peak traced memory (bytes) of reading (and checking) a recording and analysing it."""
    tracemalloc.start()
    try:
        analyze(read_for_analysis(path), estimator=estimator)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("estimator", ["periodic", "h1"])
def test_traced_memory_does_not_grow_with_the_periods(tmp_path: Path, estimator: str) -> None:
    plan = make_plan([10.0, 40.0, 160.0, 630.0], 6000, 12000, 5.0, 160.0)
    peaks = []
    for periods in (20, 160):  # both over the 16 periods of a batch
        rec = make_recording(plan, lowpass_response(), periods=periods, dut_noise_v=1e-4)
        path = tmp_path / f"r{periods}.h5"
        write_recording(path, rec)
        peaks.append(_traced_peak(path, estimator))
    # 8x the periods: whole in memory this was 2 x 160 x 96 kB of samples and their spectra
    assert peaks[1] < 1.3 * peaks[0], peaks


def test_a_read_failing_during_the_analysis_exits_2_naming_the_dataset(
    recording_file: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """The sample checks read every channel; a read after them (the analysis's batches) that
    the file refuses ends `accelcal analyze` with exit 2 and one line naming the dataset."""
    reads = {"count": 0}
    real = hdf5_stream.StoredFile.dataset

    def failing(self: hdf5_stream.StoredFile, name: str):
        reads["count"] += 1
        if reads["count"] > 2:  # the two channels checked (a block each), then the first batch
            raise OSError("Can't synchronously read data (corrupt chunk)")
        return real(self, name)

    monkeypatch.setattr(hdf5_stream.StoredFile, "dataset", failing)
    monkeypatch.setattr(hdf5_stream, "BLOCK_SAMPLES", 1 << 30)
    assert main(["analyze", str(recording_file)]) == 2
    assert reads["count"] == 3
    err = capsys.readouterr().err
    assert "rec.h5: /signals/reference: cannot be read (Can't synchronously read data" in err
    errors = [line for line in err.splitlines() if line.startswith("accelcal analyze: error")]
    assert "Traceback" not in err and len(errors) == 1


@pytest.mark.parametrize("estimator", ["periodic", "lpm"])
def test_one_estimate_for_two_chains_equals_two_analyses(recording_file: Path, estimator) -> None:
    """impact's old and new analyses (analyze_chains: read and estimated once) are each what
    `analyze` gives the recording with that chain."""
    recording = read_for_analysis(recording_file)
    corrected = dataclasses.replace(
        recording.chain,
        sensitivity_mv_per_ms2=tuple(1.01 * s for s in recording.chain.sensitivity_mv_per_ms2),
    )
    both = analyze_chains(recording, [recording.chain, corrected], estimator=estimator)
    for chain, analysis in zip((recording.chain, corrected), both, strict=True):
        alone = analyze(dataclasses.replace(recording, chain=chain), estimator=estimator)
        _numbers_equal(alone.results.to_dict(), analysis.results.to_dict())
    ratio = both[1].results.reference.sensitivity_mv_per_ms2
    ratio /= both[0].results.reference.sensitivity_mv_per_ms2
    assert ratio == pytest.approx(1.01, rel=1e-12)  # the chains did differ
