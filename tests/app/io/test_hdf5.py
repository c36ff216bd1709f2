"""Recording format: round trip, flushing, and every malformed-file case refused by name."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from app.io.csv import read_csv
from app.io.hdf5 import RecordingError, RecordingWriter, read_recording, write_recording
from app.procedure.analysis import analyze
from dsp.calibration import ReferenceChain
from dsp.multisine import make_plan
from dsp.uncertainty import Budget, Component
from tests.synthetic import lowpass_response, make_recording


@pytest.fixture(scope="module")
def plan():
    return make_plan([10.0, 40.0, 160.0, 630.0], 6000, 12000, 5.0, 160.0)


@pytest.fixture()
def recording(plan):
    budget = Budget((Component("DAQ gain", 0.002),))
    return make_recording(plan, lowpass_response(), periods=3, dut_noise_v=1e-4, budget=budget)


def test_hdf5_round_trip_keeps_everything(tmp_path, recording):
    path = tmp_path / "rec.h5"
    write_recording(path, recording)
    again = read_recording(path)
    np.testing.assert_array_equal(again.reference_v, recording.reference_v)
    np.testing.assert_array_equal(again.dut_v, recording.dut_v)
    assert again.plan == recording.plan
    assert again.chain == recording.chain and again.budget == recording.budget
    assert again.ranges_v == {"reference": 10.0, "dut": 10.0}
    with h5py.File(path) as f:
        assert f.attrs["format"] == "accelcal-recording"
        assert f["signals/dut"].chunks == (recording.period_samples,)


def test_writer_flushes_each_period_so_a_cut_run_is_readable(tmp_path, recording):
    path = tmp_path / "cut.h5"
    writer = RecordingWriter(path, recording.plan, recording.chain, recording.budget)
    n = recording.period_samples
    writer.append(recording.reference_v[:n], recording.dut_v[:n])
    writer.append(recording.reference_v[n : 2 * n], recording.dut_v[n : 2 * n])
    # the writer is not closed: another reader still sees two whole periods
    partial = read_recording(path)
    assert partial.periods == 2
    writer.close()


def test_the_runs_resolution_warnings_travel_and_a_reanalysis_states_no_such_line(
    tmp_path, recording
):
    """Issue 32 point 2: a line the run did not state (too few LSB) is not stated by a
    re-analysis of its recording either; a malformed list is refused by name."""
    path = tmp_path / "rec.h5"
    writer = RecordingWriter(path, recording.plan, recording.chain, recording.budget)
    writer.append(recording.reference_v, recording.dut_v)
    text = (
        "line 40 Hz: DUT channel 9.24 LSB on its +-0.1 V range (< 20 LSB): resolution not "
        "stated; raise the level or use a smaller input range"
    )
    writer.set_resolution_warnings([text])
    writer.close()
    again = read_recording(path)
    assert again.resolution_warnings == (text,)
    lines = analyze(again).results.lines
    assert [ln.stated for ln in lines] == [True, False, True, True]
    assert "DUT channel 9.24 LSB" in lines[1].not_stated
    with h5py.File(path, "r+") as f:
        f["config"].attrs["resolution_warnings"] = '{"a": 1}'
    with pytest.raises(RecordingError, match="'resolution_warnings' must be a list of texts"):
        read_recording(path)


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda f: f.__delitem__("signals/dut"), "missing dataset /signals/dut"),
        (lambda f: f.attrs.__setitem__("format", "other"), "not an accelcal-recording file"),
        (lambda f: f["config"].attrs.__delitem__("plan"), "missing /config attribute 'plan'"),
        (lambda f: f["config"].attrs.__setitem__("plan", "{"), "'plan' is not valid JSON"),
        (lambda f: f["signals/dut"].resize((30000,)), "channels have different lengths"),
    ],
)
def test_malformed_hdf5_is_refused_with_a_named_problem(tmp_path, recording, mutate, message):
    path = tmp_path / "bad.h5"
    write_recording(path, recording)
    with h5py.File(path, "r+") as f:
        mutate(f)
    with pytest.raises(RecordingError, match=message):
        read_recording(path)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda r, d: (r[:-7], d[:-7]), "not a whole number of periods"),
        (lambda r, d: (r, np.where(np.arange(d.size) == 5, np.nan, d)), "first NaN at sample 5"),
        (lambda r, d: (r, np.where(np.arange(d.size) == 9, np.inf, d)), "first inf at sample 9"),
        (lambda r, d: (r, np.zeros_like(d)), "channel dut: flat at 0 V: dead channel"),
        (
            lambda r, d: (np.clip(r * 1000, -9.96, 9.96), d),
            "channel reference: .* at the \\+-10 V range",
        ),
    ],
)
def test_bad_samples_are_refused(tmp_path, recording, change, message):
    reference, dut = change(recording.reference_v.copy(), recording.dut_v.copy())
    rec = recording.__class__(**{**recording.__dict__, "reference_v": reference, "dut_v": dut})
    path = tmp_path / "bad.h5"
    write_recording(path, rec)
    with pytest.raises(RecordingError, match=message):
        read_recording(path)


def test_no_period_left_after_settling(tmp_path, recording):
    rec = recording.__class__(**{**recording.__dict__, "settle_periods": 3})
    write_recording(tmp_path / "s.h5", rec)
    stored = read_recording(tmp_path / "s.h5")  # readable (e.g. an aborted run) ...
    with pytest.raises(RecordingError, match="none left after 3 settle period"):
        analyze(stored)  # ... but there is nothing to analyse


def test_not_hdf5_and_missing_file(tmp_path):
    (tmp_path / "x.h5").write_text("hello")
    with pytest.raises(RecordingError, match="not a readable HDF5 file"):
        read_recording(tmp_path / "x.h5")
    with pytest.raises(RecordingError, match="no such file"):
        read_recording(tmp_path / "none.h5")


def _csv(tmp_path, recording, header=True, rows=None):
    path = tmp_path / "rec.csv"
    data = np.column_stack([recording.reference_v, recording.dut_v])
    lines = ["reference_v,dut_v"] if header else []
    lines += rows if rows is not None else [f"{float(a)!r},{float(b)!r}" for a, b in data]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_csv_round_trip(tmp_path, recording):
    chain = ReferenceChain.flat(1.0)
    rec = read_csv(_csv(tmp_path, recording), recording.plan, chain, Budget(()))
    np.testing.assert_array_equal(rec.dut_v, recording.dut_v)
    rec = read_csv(_csv(tmp_path, recording, header=False), recording.plan, chain, Budget(()))
    assert rec.periods == 3


@pytest.mark.parametrize(
    ("rows", "message"),
    [
        (["1,2,3,4"], "line 2: 4 columns; expected 2"),
        (["1,2", "1,2,3"], "line 3: 3 columns where earlier lines have 2"),
        (["1,2", "1,abc"], "line 3: not a number in '1,abc'"),
        ([], "no data rows"),
    ],
)
def test_malformed_csv_names_the_line(tmp_path, recording, rows, message):
    path = _csv(tmp_path, recording, rows=rows)
    with pytest.raises(RecordingError, match=message):
        read_csv(path, recording.plan, ReferenceChain.flat(1.0), Budget(()))


def test_csv_clipping_detected_without_a_known_range(tmp_path, recording):
    clipped = recording.__class__(
        **{**recording.__dict__, "dut_v": np.clip(recording.dut_v, -0.05, 0.05)}
    )
    path = _csv(tmp_path, clipped)
    with pytest.raises(RecordingError, match=r"channel dut: .* consecutive samples at 0\.05 V"):
        read_csv(path, recording.plan, ReferenceChain.flat(1.0), Budget(()))
    with pytest.raises(RecordingError, match=r"at the \+-0\.05 V range limit"):
        read_csv(path, recording.plan, ReferenceChain.flat(1.0), Budget(()), range_v=0.05)
