"""The TEDS codec against NI's test files (values from docs/teds.md, computed there
by hand and checked against nidaqmx-python's own tests) and property-based round trips."""

from __future__ import annotations

from datetime import date
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hardware.teds import (
    AccelerometerTeds,
    BasicTeds,
    Teds,
    TedsError,
    TransferFunction,
    bits_from_bytes,
    bitstream_bytes,
    decode,
    encode,
    read_ted_file,
    ted_file_bytes,
)

DATA = Path(__file__).resolve().parents[1] / "data" / "teds"  # NI's files, MIT (see there)
ACCELEROMETER = DATA / "Accelerometer.ted"
VOLTAGE = DATA / "Voltage.ted"


def test_the_accelerometer_file_decodes_to_the_values_its_readme_gives() -> None:
    bits = read_ted_file(ACCELEROMETER)
    assert len(bits) == 179  # 64 + 2 + 8 + 103 + 2
    teds = decode(bits)
    assert teds.basic == BasicTeds(0, 0, 0, 0, 0)
    assert (teds.selector, teds.template_id) == (0, 25)
    a = teds.accelerometer
    assert a is not None and a.sensitivity_code == 53735
    assert a.sensitivity_v_per_ms2 == pytest.approx(4.99993, abs=1e-5)
    assert a.sensitivity_v_per_ms2 * 9.80665 == pytest.approx(49.03, abs=5e-3)  # nidaqmx: V/g
    assert a.high_pass_hz == 0.005 and a.weight_g == 0.1
    assert a.reference_frequency_hz == 0.35 and a.reference_temperature_c == 15.0
    assert a.calibration_date == date(1998, 1, 1) and a.transfer_function is None
    assert teds.trailing_bits == (1, 1)  # the end selector, 3


def test_the_voltage_file_gives_nidaqmx_s_basic_teds_and_bitstream() -> None:
    bits = read_ted_file(VOLTAGE)
    teds = decode(bits)
    assert teds.basic == BasicTeds(17, 1, 1, 1, 12345)
    assert teds.basic.version_letter == "A"
    assert teds.basic.identity == "17/1/A1/12345"
    assert teds.template_id == 30 and teds.accelerometer is None
    # nidaqmx-python's test expects teds_bit_stream to start [17, 64, 0, 32, 4, 57, 48, ...]
    assert bitstream_bytes(bits)[:7] == bytes([17, 64, 0, 32, 4, 57, 48])


@pytest.mark.parametrize("path", [ACCELEROMETER, VOLTAGE])
def test_both_files_encode_back_to_the_same_bytes(path: Path) -> None:
    bits = read_ted_file(path)
    assert encode(decode(bits)) == bits
    assert ted_file_bytes(encode(decode(bits))) == path.read_bytes()
    assert bits_from_bytes(bitstream_bytes(bits), len(bits)) == bits


def test_a_new_sensitivity_is_coded_to_its_step() -> None:
    a = decode(read_ted_file(ACCELEROMETER)).accelerometer
    assert a is not None
    # 10 mV/(m/s^2) = 0.01 V/(m/s^2): code = ln(0.01 / 5e-7) / ln(1.0003) = 33016.9 -> 33017
    new = a.with_sensitivity(10.0, date(2026, 11, 23), "ab")
    assert new.sensitivity_code == 33017
    assert new.sensitivity_mv_per_ms2 == pytest.approx(10.0, rel=1.5e-4)  # half a 0.03 % step
    assert new.calibration_date == date(2026, 11, 23) and new.calibration_initials == "AB "
    with pytest.raises(TedsError, match=r"^sensitivity: 1e\+06 mV/\(m/s\^2\) is outside"):
        a.with_sensitivity(1e6, date(2026, 1, 1))
    with pytest.raises(TedsError, match=r"^calibration initials"):
        a.with_sensitivity(10.0, date(2026, 1, 1), "ABCD")


def test_bad_streams_are_refused_naming_the_field(tmp_path: Path) -> None:
    bits = read_ted_file(ACCELEROMETER)
    # basic 64 + selector 2 + id 8 + 2 + 16 + 8 + 2 + 6 + 1 + 1 + 8 = 118: reference temperature
    with pytest.raises(TedsError, match=r"^reference temperature: the bitstream ends at bit 120"):
        decode(bits[:120])
    force = list(bits)
    force[74] = 1  # the acceleration/force selector after basic (64) + selector (2) + id (8)
    with pytest.raises(TedsError, match="force branch"):
        decode(force)
    bad = tmp_path / "bad.ted"
    bad.write_bytes(b"\x02" * 100)
    with pytest.raises(TedsError, match=r"no NI \.ted header"):
        read_ted_file(bad)


def codes(width: int) -> st.SearchStrategy[int]:
    return st.integers(0, (1 << width) - 1)


accelerometers = st.builds(
    AccelerometerTeds,
    sensitivity_code=codes(16),
    high_pass_code=codes(8),
    direction=codes(2),
    weight_code=codes(6),
    polarity=codes(1),
    transfer_function=st.none()
    | st.builds(TransferFunction, codes(7), codes(9), codes(9), codes(7), codes(6)),
    reference_frequency_code=codes(8),
    reference_temperature_code=codes(5),
    calibration_date_code=codes(16),
    calibration_initials_codes=st.tuples(codes(5), codes(5), codes(5)),
    calibration_period_days=codes(12),
    measurement_location_id=codes(11),
)


@given(
    basic=st.builds(BasicTeds, codes(14), codes(15), codes(5), codes(6), codes(24)),
    accelerometer=accelerometers,
    trailing=st.lists(st.integers(0, 1), max_size=16).map(tuple),
)
def test_any_field_values_round_trip_bit_exactly(
    basic: BasicTeds, accelerometer: AccelerometerTeds, trailing: tuple[int, ...]
) -> None:
    teds = Teds(basic, 0, 25, accelerometer, trailing)
    bits = encode(teds)
    width = 64 + 10 + 2 + 16 + 8 + 2 + 6 + 1 + 1 + 8 + 5 + 16 + 15 + 12 + 11
    width += 38 if accelerometer.transfer_function is not None else 0
    assert len(bits) == width + len(trailing)
    assert decode(bits) == teds
    assert encode(decode(bits)) == bits
