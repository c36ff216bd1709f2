"""`accelcal analyze rec.tdms` (issue 16 point 6) on files written with npTDMS's writer."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from app.cli import main
from app.io.hdf5 import RecordingError, write_recording
from app.io.tdms import SKEW_PROPERTY, inspect_tdms
from app.procedure.phase_store import stored_phases
from dsp.multisine import preset_plan
from tests.synthetic import lowpass_response, make_recording, write_tdms
from tests.within_u import assert_consistent_with_u

SKEW_S = 3e-6
PLAN_OPTIONS = ["--preset", "piezo", "--reference-sensitivity", "1"]


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A piezo-plan recording (6 kS/s) of the known low-pass DUT sampled SKEW_S late, with
    noise on both channels, as TDMS with the skew as a file property."""
    rec = make_recording(
        preset_plan("piezo", optimiser=stored_phases),
        lowpass_response(),
        periods=8,
        reference_noise_v=2e-4,
        dut_noise_v=2e-3,
        skew_s=SKEW_S,
        seed=7,
    )
    folder = tmp_path_factory.mktemp("tdms")
    path = folder / "rec.tdms"
    write_tdms(path, rec, group="accel", names=("ref", "dut"), skew_s=SKEW_S)
    return path, rec


def _analyze(capsys, path, *extra):
    return run(
        capsys, "analyze", str(path), *PLAN_OPTIONS, "--reference", "accel/ref", "--dut", "dut",
        "--json", *extra,
    )  # fmt: skip


def test_known_answer_recovered_within_u(capsys, recorded):
    """Sample rate from wf_increment, skew from the property: magnitude and phase consistent
    with U at every line (tests/within_u.py: 2.13 U over these 50 comparisons)."""
    path, rec = recorded
    code, out, err = _analyze(capsys, path)
    assert code == 0, err
    data = json.loads(out)
    assert data["phase_corrected_for_skew"] is True
    truth = lowpass_response()(rec.plan.frequencies_hz)
    got = np.array([ln["sensitivity_mv_per_ms2"] for ln in data["lines"]])
    u = np.array([ln["expanded_uncertainty_mv_per_ms2"] for ln in data["lines"]])
    k = np.array([ln["coverage_factor"] for ln in data["lines"]])
    assert len(got) == 25
    phase = np.array([ln["phase_deg"] for ln in data["lines"]])
    u_phase = np.array([ln["phase_expanded_uncertainty_deg"] for ln in data["lines"]])
    k_phase = np.array([ln["phase_coverage_factor"] for ln in data["lines"]])
    error = (phase - np.degrees(np.angle(truth)) + 180) % 360 - 180
    # uncorrected, the 3 us skew would be 1.1 deg at 1 kHz (4 U: U 0.27 deg) and 2.7 deg at
    # 2.5 kHz (2.25 U: U 1.2 deg), both beyond the bound
    assert_consistent_with_u(
        ("magnitude", got - np.abs(truth), u, k), ("phase", error, u_phase, k_phase)
    )


def test_skew_option_and_property(capsys, recorded, tmp_path):
    path, rec = recorded
    code, _, err = _analyze(capsys, path, "--skew", "-2e-06")
    assert code == 2
    assert f"rec.tdms: --skew -2e-06 s disagrees with the file's {SKEW_PROPERTY} = 3e-06 s" in err
    code, _, err = _analyze(capsys, path, "--skew", str(SKEW_S))
    assert code == 0, err
    bare = tmp_path / "bare.tdms"  # no property, no option: the phase is not corrected
    write_tdms(bare, rec, group="accel", names=("ref", "dut"))
    code, out, err = _analyze(capsys, bare)
    assert code == 0, err
    assert json.loads(out)["phase_corrected_for_skew"] is False


def test_skew_property_of_the_dut_channel_first(recorded, tmp_path):
    _, rec = recorded
    path = tmp_path / "both.tdms"
    write_tdms(path, rec, names=("ref", "dut"), skew_s=1e-6, properties={SKEW_PROPERTY: 5e-6})
    assert inspect_tdms(path, "ref", "dut").skew_s == 5e-6
    write_tdms(path, rec, names=("ref", "dut"), skew_s=1e-6)
    assert inspect_tdms(path, "ref", "dut").skew_s == 1e-6
    write_tdms(path, rec, names=("ref", "dut"), properties={SKEW_PROPERTY: 2.0})
    with pytest.raises(RecordingError, match=r"accelcal_skew_s of channel accel/dut: 2 is not"):
        inspect_tdms(path, "ref", "dut")


def test_wrong_channel_refused_listing_the_channels(capsys, recorded):
    path, _ = recorded
    code, _, err = run(
        capsys, "analyze", str(path), *PLAN_OPTIONS, "--reference", "accel/ref", "--dut", "dot"
    )
    assert code == 2
    assert "--dut: no channel 'dot' in rec.tdms; it has: accel/ref, accel/dut" in err
    code, _, err = run(capsys, "analyze", str(path), *PLAN_OPTIONS, "--dut", "dut")
    assert code == 2
    assert "--reference: a TDMS recording needs it" in err and "accel/ref, accel/dut" in err
    code, _, err = run(capsys, "analyze", str(path), *PLAN_OPTIONS, "--reference", "dut",
                       "--dut", "accel/dut")  # fmt: skip
    assert code == 2 and "both name accel/dut" in err


def test_a_name_in_two_groups_needs_its_group(recorded, tmp_path):
    from nptdms import ChannelObject, TdmsWriter

    _, rec = recorded
    path = tmp_path / "two.tdms"
    props = {"wf_increment": 1 / 6000}
    with TdmsWriter(str(path)) as writer:
        writer.write_segment(
            [
                ChannelObject("a", "x", rec.reference_v, properties=props),
                ChannelObject("b", "x", rec.dut_v, properties=props),
            ]
        )
    with pytest.raises(RecordingError, match=r"'x' names 2 channels of two.tdms \(a/x, b/x\)"):
        inspect_tdms(path, "x", "b/x")
    source = inspect_tdms(path, "a/x", "b/x")
    assert (source.reference, source.dut, source.sample_rate_hz) == (("a", "x"), ("b", "x"), 6000)


@pytest.mark.parametrize("cut", [-1000, -24010, 20, 3])
def test_truncated_file_refused_naming_it(capsys, recorded, tmp_path, cut):
    """Cut inside the last segment's data, inside a segment's lead-in, in the first one."""
    path, _ = recorded
    data = path.read_bytes()
    short = tmp_path / "cut.tdms"
    short.write_bytes(data[:cut])
    code, _, err = _analyze(capsys, short)
    assert code == 2
    assert "cut.tdms" in err and ("truncated" in err or "not a TDMS file" in err), err


def test_unclosed_segment_refused(recorded, tmp_path):
    """A segment whose writer stopped (next-segment offset all ones, as LabVIEW leaves it)."""
    path, _ = recorded
    data = bytearray(path.read_bytes())
    data[12:20] = b"\xff" * 8
    bad = tmp_path / "open.tdms"
    bad.write_bytes(bytes(data))
    with pytest.raises(RecordingError, match=r"open.tdms: truncated: .* never closed"):
        inspect_tdms(bad, "ref", "dut")


def test_not_tdms_and_not_a_regular_file(capsys, tmp_path):
    text = tmp_path / "text.tdms"
    text.write_text("reference,dut\n1,2\n")
    code, _, err = _analyze(capsys, text)
    assert code == 2 and "text.tdms: not a TDMS file" in err
    fifo = tmp_path / "pipe.tdms"
    os.mkfifo(fifo)
    code, _, err = _analyze(capsys, fifo)
    assert code == 2 and "is a FIFO (named pipe); a TDMS recording must be a regular file" in err
    code, _, err = _analyze(capsys, tmp_path / "none.tdms")
    assert code == 2 and "none.tdms: no such file" in err


def test_sample_rate_from_the_file_or_the_option(capsys, recorded, tmp_path):
    path, rec = recorded
    code, _, err = _analyze(capsys, path, "--sample-rate", "5000")
    assert code == 2
    assert "--sample-rate: 5000 Hz disagrees with rec.tdms's 6000 Hz (1 / wf_increment)" in err
    bare = tmp_path / "norate.tdms"
    write_tdms(bare, rec, group="accel", names=("ref", "dut"), skew_s=SKEW_S)
    fast = tmp_path / "fast.tdms"  # a rate the plan cannot have (its lines off their bins)
    write_tdms(fast, rec, group="accel", names=("ref", "dut"), properties={"wf_increment": 1e-4})
    code, _, err = _analyze(capsys, fast)
    assert code == 2 and "line" in err
    from nptdms import ChannelObject, TdmsWriter

    with TdmsWriter(str(bare)) as writer:
        writer.write_segment(
            [
                ChannelObject("accel", "ref", rec.reference_v),
                ChannelObject("accel", "dut", rec.dut_v),
            ]
        )
    code, _, err = _analyze(capsys, bare)
    assert code == 2 and "--sample-rate: norate.tdms states none (no wf_increment)" in err
    code, _, err = _analyze(capsys, bare, "--sample-rate", "6000")
    assert code == 0, err


def test_channels_not_in_volts_refused(recorded, tmp_path):
    _, rec = recorded
    path = tmp_path / "ms2.tdms"
    write_tdms(path, rec, names=("ref", "dut"), properties={"unit_string": "m/s^2"})
    with pytest.raises(RecordingError, match=r"channel accel/ref: unit_string 'm/s\^2'"):
        inspect_tdms(path, "ref", "dut")


def test_tdms_options_refused_for_other_files(capsys, tmp_path):
    plan = preset_plan("piezo", optimiser=stored_phases)
    rec = make_recording(plan, lowpass_response(), periods=3, dut_noise_v=1e-3)
    h5 = tmp_path / "rec.h5"
    write_recording(h5, rec)
    code, _, err = run(capsys, "analyze", str(h5), "--dut", "dut")
    assert code == 2 and "--dut: not allowed with an HDF5 recording" in err
    csv = tmp_path / "rec.csv"
    csv.write_text("1,2\n3,4\n")
    code, _, err = run(capsys, "analyze", str(csv), *PLAN_OPTIONS, "--reference", "a")
    assert code == 2 and "--reference, --dut: TDMS channels" in err
