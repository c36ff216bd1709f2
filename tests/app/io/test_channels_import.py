"""Several-DUT recordings from CSV and TDMS (issue 36 point 4): one two-channel Recording per
DUT channel, named as the design says (`dut.<position>`), refusals naming the column or
channel; the single-DUT readers are untouched (their own tests)."""

from __future__ import annotations

import numpy as np
import pytest

from app.io.csv import read_csv, read_csv_channels, several_dut_columns
from app.io.hdf5 import RecordingError
from app.io.tdms import SKEW_PROPERTY, inspect_tdms_channels, read_tdms_channels
from app.procedure.analysis import analyze
from dsp.calibration import ReferenceChain
from dsp.multisine import make_plan
from dsp.uncertainty import Budget
from tests.synthetic import channel_periods

PLAN = make_plan([100.0, 200.0, 400.0], 2000.0, 40, 1.0, 100.0, phases_rad=[0.0, 0.5, 1.0])
CHAIN = ReferenceChain.flat(1.0, skew_s=None)  # the file states the skews
PERIODS = 6
GAINS = {"dut.A": 1.0, "dut.B": 2.0, "dut.T.x": 0.5}  # V/V behind the same 10 mV/(m/s^2)


def _signals(seed: int = 3) -> dict[str, np.ndarray]:
    """reference (1 mV/(m/s^2)), three DUT channels of 10 mV/(m/s^2) behind GAINS, drive."""
    rng = np.random.default_rng(seed)
    flat = np.ones(len(PLAN.lines), dtype=complex)
    out = {"reference": np.tile(channel_periods(PLAN, flat), PERIODS)}
    for name, gain in GAINS.items():
        period = channel_periods(PLAN, 10.0 * flat, gain)
        out[name] = np.tile(period, PERIODS) + 1e-5 * rng.standard_normal(PERIODS * 40)
    out["drive"] = 0.5 * out["reference"] + 1e-4 * rng.standard_normal(PERIODS * 40)
    return out


def _csv(path, signals, order, comments=()):
    rows = np.column_stack([signals[c] for c in order])
    body = "\n".join(",".join(repr(float(v)) for v in row) for row in rows)
    path.write_text("\n".join([*comments, ",".join(order), body]) + "\n", encoding="utf-8")
    return path


def test_csv_gives_one_recording_per_dut_column_in_header_order(tmp_path):
    signals = _signals()
    order = ["dut.B", "reference", "dut.T.x", "drive", "dut.A"]
    members = read_csv_channels(_csv(tmp_path / "rec.csv", signals, order), PLAN, CHAIN, Budget(()))
    assert list(members) == ["dut.B", "dut.T.x", "dut.A"]
    first = members["dut.B"]
    for channel, recording in members.items():
        np.testing.assert_array_equal(recording.dut_v, signals[channel])
        np.testing.assert_array_equal(recording.reference_v, signals["reference"])
        assert recording.reference_v is first.reference_v  # shared, not copied
        assert recording.drive_v is not None
        np.testing.assert_array_equal(recording.drive_v, signals["drive"])
        assert recording.source.endswith(f"rec.csv#{channel}")


def test_each_member_analyses_as_its_own_dut(tmp_path):
    """The estimator on (reference, dut.<p>) finds each channel's own gain x 10 mV/(m/s^2)."""
    signals = _signals()
    path = _csv(tmp_path / "rec.csv", signals, ["reference", *GAINS])
    members = read_csv_channels(path, PLAN, CHAIN, Budget(()))
    for channel, gain in GAINS.items():
        lines = analyze(members[channel]).results.lines
        found = np.array([line.sensitivity_mv_per_ms2 for line in lines])
        np.testing.assert_allclose(found, 10.0 * gain, rtol=1e-3)


def test_csv_skews_per_channel_and_for_the_rest(tmp_path):
    comments = ["# skew_s[dut.A] = 2e-06", "# skew_s = 5e-06"]
    path = _csv(tmp_path / "s.csv", _signals(), ["reference", "dut.A", "dut.B"], comments)
    members = read_csv_channels(path, PLAN, CHAIN, Budget(()))
    assert members["dut.A"].chain.skew_s == 2e-06
    assert members["dut.B"].chain.skew_s == 5e-06
    with pytest.raises(RecordingError, match=r"--skew 1e-06 s disagrees with .*skew_s\[dut\.A\]"):
        read_csv_channels(path, PLAN, ReferenceChain.flat(1.0, skew_s=1e-6), Budget(()))


@pytest.mark.parametrize(
    ("header", "message"),
    [
        ("reference,dut_A,dut.B", r"line 1: column 2 'dut_A': not a channel name"),
        ("reference,dut.A,dut.A", r"line 1: column 3 'dut.A': named twice"),
        ("ref,dut.A,dut.B", r"line 1: column 1 'ref': not a channel name"),
        ("dut.A,dut.B,drive", r"line 1: no column named 'reference'"),
        ("reference,drive,drive", r"line 1: column 3 'drive': named twice"),
        ("reference,drive", r"line 1: no DUT column"),
        ("reference,dut.A.x.y,drive", r"line 1: column 2 'dut.A.x.y': not a"),
        ("reference,dut.this-name-is-too-long,drive", r"line 1: column 2 'dut.this-name-is-t"),
    ],
)
def test_csv_header_refused_naming_the_column(tmp_path, header, message):
    path = tmp_path / "bad.csv"
    path.write_text(header + "\n" + "0.1,0.2,0.3\n" * 80, encoding="utf-8")
    with pytest.raises(RecordingError, match=rf"bad\.csv: {message}"):
        read_csv_channels(path, PLAN, CHAIN, Budget(()))


def test_csv_without_header_or_with_a_short_row_refused_naming_the_line(tmp_path):
    signals = _signals()
    path = tmp_path / "nohead.csv"
    path.write_text("0.1,0.2,0.3\n" * 80, encoding="utf-8")
    with pytest.raises(RecordingError, match=r"nohead\.csv: line 1: .*needs a header line"):
        read_csv_channels(path, PLAN, CHAIN, Budget(()))
    path = _csv(tmp_path / "short.csv", signals, ["reference", "dut.A", "dut.B"])
    lines = path.read_text().splitlines()
    lines[5] = ",".join(lines[5].split(",")[:2])
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(RecordingError, match=r"short\.csv: line 6: 2 columns where"):
        read_csv_channels(path, PLAN, CHAIN, Budget(()))
    path = tmp_path / "skew.csv"
    _csv(path, signals, ["reference", "dut.A"], ["# skew_s[dut.B] = 1e-6"])
    with pytest.raises(RecordingError, match=r"skew_s\[dut\.B\]: no DUT column 'dut\.B'"):
        read_csv_channels(path, PLAN, CHAIN, Budget(()))


def test_csv_dead_dut_channel_refused_naming_its_column(tmp_path):
    signals = _signals()
    signals["dut.B"] = np.zeros_like(signals["dut.B"])
    path = _csv(tmp_path / "dead.csv", signals, ["reference", "dut.A", "dut.B"])
    with pytest.raises(RecordingError, match=r"dead\.csv: column 3 dut\.B"):
        read_csv_channels(path, PLAN, CHAIN, Budget(()))


def test_single_dut_csv_reader_still_refuses_more_columns(tmp_path):
    path = _csv(tmp_path / "four.csv", _signals(), ["reference", "dut.A", "dut.B", "drive"])
    with pytest.raises(RecordingError, match=r"4 columns; expected 2 \(reference, DUT\)"):
        read_csv(path, PLAN, CHAIN, Budget(()))


def _tdms(path, signals, *, group="accel", names=None, properties=None, file_skew=None):
    """`signals` as channels of one group (names: channel name per signal key)."""
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    names = names or {}
    root = RootObject({} if file_skew is None else {SKEW_PROPERTY: file_skew})
    with TdmsWriter(str(path)) as writer:
        channels = [
            ChannelObject(
                group,
                names.get(key, key),
                x,
                properties={
                    "wf_increment": 1.0 / PLAN.sample_rate_hz,
                    "unit_string": "V",
                    **(properties or {}).get(key, {}),
                },
            )
            for key, x in signals.items()
        ]
        writer.write_segment([root, GroupObject(group), *channels])
    return path


def test_tdms_channels_found_by_name_with_their_own_skews(tmp_path):
    signals = _signals()
    path = _tdms(
        tmp_path / "rec.tdms",
        signals,
        properties={"dut.A": {SKEW_PROPERTY: 2e-6}},
        file_skew=4e-6,
    )
    source = inspect_tdms_channels(path)
    assert list(source.duts) == list(GAINS)
    assert source.drive == ("accel", "drive") and source.sample_rate_hz == 2000.0
    assert source.skews_s == {"dut.A": 2e-6, "dut.B": 4e-6, "dut.T.x": 4e-6}
    members = read_tdms_channels(path, PLAN, CHAIN, Budget(()), source=source)
    assert members["dut.A"].chain.skew_s == 2e-6 and members["dut.B"].chain.skew_s == 4e-6
    for channel in GAINS:
        np.testing.assert_array_equal(members[channel].dut_v, signals[channel])
        assert members[channel].reference_v is members["dut.A"].reference_v


def test_tdms_channels_named_by_a_mapping(tmp_path):
    signals = _signals()
    names = {"reference": "ai0", "dut.A": "ai1", "dut.B": "ai2", "dut.T.x": "ai3", "drive": "ai9"}
    path = _tdms(tmp_path / "daq.tdms", signals, names=names)
    members = read_tdms_channels(
        path,
        PLAN,
        CHAIN,
        Budget(()),
        reference="accel/ai0",
        duts={"dut.A": "ai1", "dut.B": "accel/ai2"},
        drive="ai9",
    )
    assert list(members) == ["dut.A", "dut.B"]
    np.testing.assert_array_equal(members["dut.B"].dut_v, signals["dut.B"])
    np.testing.assert_array_equal(members["dut.B"].drive_v, signals["drive"])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"reference": "ai0", "duts": {"A": "ai1"}}, r"daq\.tdms: DUT channel name 'A': not"),
        ({"reference": "ai0", "duts": {"dut.A": "ai7"}}, r"dut\.A: no channel 'ai7' in daq.*ai9"),
        ({"reference": "ai0", "duts": {"dut.A": "ai0"}}, r"daq\.tdms: reference and dut\.A both"),
        ({"duts": {"dut.A": "ai1"}}, r"reference: no channel 'reference' in daq\.tdms"),
        ({"reference": "ai0"}, r"daq\.tdms: no DUT channel \(named 'dut' or 'dut\.<position>'\)"),
    ],
)
def test_tdms_refusals_name_the_channel(tmp_path, kwargs, message):
    names = {"reference": "ai0", "dut.A": "ai1", "dut.B": "ai2", "dut.T.x": "ai3", "drive": "ai9"}
    path = _tdms(tmp_path / "daq.tdms", _signals(), names=names)
    with pytest.raises(RecordingError, match=message):
        inspect_tdms_channels(path, **kwargs)


def test_tdms_channel_not_in_volts_refused_naming_it(tmp_path):
    path = _tdms(tmp_path / "g.tdms", _signals(), properties={"dut.B": {"unit_string": "g"}})
    with pytest.raises(RecordingError, match=r"channel accel/dut\.B \(dut\.B\): unit_string 'g'"):
        inspect_tdms_channels(path)


def test_several_dut_columns_tells_the_two_kinds_of_csv_apart(tmp_path):
    signals = _signals()
    several = _csv(tmp_path / "n.csv", signals, ["reference", "dut.A", "drive", "dut.T.x"], ["# x"])
    assert several_dut_columns(several) == ("dut.A", "dut.T.x")
    for header in ("reference_v,dut_v", "reference,dut,drive"):
        single = tmp_path / "one.csv"
        single.write_text(header + "\n0.1,0.2,0.3\n", encoding="utf-8")
        assert several_dut_columns(single) == ()
    single.write_text("0.1,0.2\n", encoding="utf-8")
    assert several_dut_columns(single) == ()
    single.write_text("reference,dut.A,dut.A\n", encoding="utf-8")
    with pytest.raises(RecordingError, match=r"column 3 'dut\.A': named twice"):
        several_dut_columns(single)


@pytest.mark.parametrize("newline", ["\r", "\r\n", "\n"])
def test_csv_of_any_line_end_and_semicolons_reads_the_same(tmp_path, newline):
    signals = _signals()
    order = ["reference", "dut.A", "dut.B"]
    text = _csv(tmp_path / "a.csv", signals, order, ["# skew_s[dut.B] = 1e-06"]).read_text()
    path = tmp_path / "b.csv"
    path.write_bytes(text.replace(",", ";").replace("\n", newline).encode())
    members = read_csv_channels(path, PLAN, CHAIN, Budget(()))
    np.testing.assert_array_equal(members["dut.B"].dut_v, signals["dut.B"])
    assert members["dut.B"].chain.skew_s == 1e-06 and members["dut.A"].chain.skew_s is None
