"""IEEE 1451.4 TEDS: Basic TEDS and Template 25 (IEPE accelerometer), bit-exact both ways.

The layout and the data types are those of docs/teds.md (checked there against NI's
test files and nidaqmx-python): every field is an unsigned integer sent least significant bit
first, with no byte alignment. Physical values are stored as codes:

    ConRelRes   value = start * (1 + 2 * tolerance) ** code
    ConRes      value = start + step * code
    Date        days since 1998-01-01
    Chr5        letter = chr(64 + code), 1 = 'A' ... 26 = 'Z'

A decoded TEDS keeps every code, so encode(decode(bits)) == bits; the physical values are
derived properties, and `with_sensitivity` sets a new sensitivity (and calibration date) by
code. An NI `.ted` file holds one bit per byte after a 40-bit header; `bitstream_bytes` packs
the bits LSB first into bytes, as nidaqmx's PhysicalChannel.teds_bit_stream gives them;
`ChannelTeds` is one input channel's read (hardware.nidaq.read_teds_channels): bytes or why none.
Template 25's extended-functionality and force branches, not verified on data, are refused.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from datetime import date, timedelta
from pathlib import Path

from hardware.errors import InputRefused

TED_FILE_HEADER = tuple(int(c) for c in "1101101001101110000011001100110010111010")
TEDS_EPOCH = date(1998, 1, 1)
STANDARD_GRAVITY_MS2 = 9.80665
TEMPLATE_ACCELEROMETER = 25
MAX_TEDS_BITS = 8 * 1024  # a 1451.4 memory is at most a few hundred bytes


class TedsError(InputRefused):
    """A bitstream or value that is no TEDS we can read or write; the message names the field."""


@dataclass(frozen=True)
class ConRelRes:
    """A field coded as start * (1 + 2 * tolerance) ** code, `bits` wide."""

    bits: int
    start: float
    tolerance: float

    def value(self, code: int) -> float:
        return self.start * (1.0 + 2.0 * self.tolerance) ** code

    def code(self, value: float, field: str) -> int:
        if not (math.isfinite(value) and value > 0):
            raise TedsError(f"{field}: must be a finite number > 0, got {value!r}")
        code = round(math.log(value / self.start) / math.log1p(2.0 * self.tolerance))
        if not 0 <= code < 1 << self.bits:
            low, high = self.value(0), self.value((1 << self.bits) - 1)
            raise TedsError(f"{field}: {value:g} is outside {low:.6g} ... {high:.6g}")
        return code


@dataclass(frozen=True)
class ConRes:
    """A field coded as start + step * code, `bits` wide."""

    bits: int
    start: float
    step: float

    def value(self, code: int) -> float:
        return self.start + self.step * code


# Template 25 field codings (README table; units in the names)
SENSITIVITY_V_PER_MS2 = ConRelRes(16, 5e-7, 0.00015)
HIGH_PASS_HZ = ConRelRes(8, 0.005, 0.03)
WEIGHT_G = ConRelRes(6, 0.1, 0.10)
LOW_PASS_HZ = ConRelRes(7, 10.0, 0.05)
RESONANCE_HZ = ConRelRes(9, 100.0, 0.01)
QUALITY_FACTOR = ConRelRes(9, 0.4, 0.01)
AMPLITUDE_SLOPE_PERCENT_PER_DECADE = ConRes(7, -6.3, 0.1)
TEMPERATURE_COEFFICIENT_PERCENT_PER_C = ConRes(6, -0.8, 0.025)
REFERENCE_FREQUENCY_HZ = ConRelRes(8, 0.35, 0.0175)
REFERENCE_TEMPERATURE_C = ConRes(5, 15.0, 0.5)


class _Reader:
    """Fields off a bit sequence, LSB first; a short stream is refused naming the field."""

    def __init__(self, bits: tuple[int, ...]) -> None:
        self.bits, self.position = bits, 0

    def take(self, width: int, field: str) -> int:
        end = self.position + width
        if end > len(self.bits):
            raise TedsError(
                f"{field}: the bitstream ends at bit {len(self.bits)}, the field needs bits "
                f"{self.position}..{end - 1}"
            )
        value = sum(bit << i for i, bit in enumerate(self.bits[self.position : end]))
        self.position = end
        return value

    def rest(self) -> tuple[int, ...]:
        return self.bits[self.position :]


def _put(out: list[int], value: int, width: int, field: str) -> None:
    if not 0 <= value < 1 << width:
        raise TedsError(f"{field}: code {value} does not fit in {width} bits")
    out.extend((value >> i) & 1 for i in range(width))


@dataclass(frozen=True)
class BasicTeds:
    """The 64-bit Basic TEDS: manufacturer id, model, version letter and number, serial."""

    manufacturer_id: int
    model_number: int
    version_letter_code: int
    version_number: int
    serial_number: int

    WIDTHS = (
        ("manufacturer_id", 14),
        ("model_number", 15),
        ("version_letter_code", 5),
        ("version_number", 6),
        ("serial_number", 24),
    )

    @property
    def version_letter(self) -> str:
        """'A' ... 'Z' ('' for code 0 or a code past 'Z')."""
        return chr(64 + self.version_letter_code) if 1 <= self.version_letter_code <= 26 else ""

    @property
    def identity(self) -> str:
        """'manufacturer/model/version/serial' as the records keep a sensor's TEDS identity."""
        version = f"{self.version_letter}{self.version_number}"
        return f"{self.manufacturer_id}/{self.model_number}/{version}/{self.serial_number}"


@dataclass(frozen=True)
class TransferFunction:
    """Template 25's optional transfer-function block, as codes."""

    low_pass_code: int
    resonance_code: int
    quality_factor_code: int
    amplitude_slope_code: int
    temperature_coefficient_code: int

    WIDTHS = (
        ("low_pass_code", 7),
        ("resonance_code", 9),
        ("quality_factor_code", 9),
        ("amplitude_slope_code", 7),
        ("temperature_coefficient_code", 6),
    )


@dataclass(frozen=True)
class AccelerometerTeds:
    """Template 25, acceleration case without extended functionality, as codes."""

    sensitivity_code: int
    high_pass_code: int
    direction: int
    weight_code: int
    polarity: int
    transfer_function: TransferFunction | None
    reference_frequency_code: int
    reference_temperature_code: int
    calibration_date_code: int
    calibration_initials_codes: tuple[int, int, int]
    calibration_period_days: int
    measurement_location_id: int

    @property
    def sensitivity_v_per_ms2(self) -> float:
        """Sensitivity at the reference conditions, V/(m/s^2)."""
        return SENSITIVITY_V_PER_MS2.value(self.sensitivity_code)

    @property
    def sensitivity_mv_per_ms2(self) -> float:
        """The same in mV/(m/s^2), the unit of the records and results."""
        return 1e3 * self.sensitivity_v_per_ms2

    @property
    def reference_frequency_hz(self) -> float:
        return REFERENCE_FREQUENCY_HZ.value(self.reference_frequency_code)

    @property
    def reference_temperature_c(self) -> float:
        return REFERENCE_TEMPERATURE_C.value(self.reference_temperature_code)

    @property
    def high_pass_hz(self) -> float:
        return HIGH_PASS_HZ.value(self.high_pass_code)

    @property
    def weight_g(self) -> float:
        return WEIGHT_G.value(self.weight_code)

    @property
    def calibration_date(self) -> date:
        return TEDS_EPOCH + timedelta(days=self.calibration_date_code)

    @property
    def calibration_initials(self) -> str:
        return "".join(
            chr(64 + c) if 1 <= c <= 26 else " " for c in self.calibration_initials_codes
        )

    def with_sensitivity(
        self, sensitivity_mv_per_ms2: float, calibrated: date, initials: str = ""
    ) -> AccelerometerTeds:
        """A copy holding a new sensitivity (mV/(m/s^2), to the code's 0.03 % step) and
        calibration date (and initials, up to 3 letters A-Z)."""
        coding = SENSITIVITY_V_PER_MS2
        try:
            code = coding.code(sensitivity_mv_per_ms2 / 1e3, "sensitivity")
        except TedsError:
            low, high = 1e3 * coding.value(0), 1e3 * coding.value((1 << coding.bits) - 1)
            raise TedsError(
                f"sensitivity: {sensitivity_mv_per_ms2:g} mV/(m/s^2) is outside "
                f"{low:.6g} ... {high:.6g} mV/(m/s^2)"
            ) from None
        days = (calibrated - TEDS_EPOCH).days
        if not 0 <= days < 1 << 16:
            raise TedsError(f"calibration date: {calibrated} is outside 1998-01-01 ... 2177")
        letters = initials.upper()
        if len(letters) > 3 or any(not "A" <= c <= "Z" for c in letters):
            raise TedsError(f"calibration initials: up to 3 letters A-Z, got {initials!r}")
        codes = tuple(ord(c) - 64 for c in letters.ljust(3, "@"))
        return dataclasses.replace(
            self,
            sensitivity_code=code,
            calibration_date_code=days,
            calibration_initials_codes=(codes[0], codes[1], codes[2]),
        )


@dataclass(frozen=True)
class Teds:
    """A whole TEDS: Basic TEDS, template selector and id, the accelerometer template when the id
    is 25, and every remaining bit as it was (so encoding gives back the same bits)."""

    basic: BasicTeds
    selector: int
    template_id: int
    accelerometer: AccelerometerTeds | None
    trailing_bits: tuple[int, ...]


def decode(bits: tuple[int, ...] | list[int]) -> Teds:
    """A TEDS from its bits (0/1, transmission order)."""
    bits = tuple(int(b) for b in bits)
    if any(b not in (0, 1) for b in bits):
        raise TedsError("bitstream: every element must be 0 or 1")
    r = _Reader(bits)
    basic = BasicTeds(**{name: r.take(width, name) for name, width in BasicTeds.WIDTHS})
    selector = r.take(2, "template selector")
    template_id = r.take(8, "template id")
    accelerometer = None
    if selector == 0 and template_id == TEMPLATE_ACCELEROMETER:
        accelerometer = _decode_accelerometer(r)
    return Teds(basic, selector, template_id, accelerometer, r.rest())


def _decode_accelerometer(r: _Reader) -> AccelerometerTeds:
    if r.take(1, "acceleration/force selector") != 0:
        raise TedsError("template 25: the force branch is not supported (accelerometers only)")
    if r.take(1, "extended functionality selector") != 0:
        raise TedsError("template 25: extended functionality is not supported")
    sensitivity = r.take(16, "sensitivity")
    high_pass = r.take(8, "high-pass cut-off")
    direction = r.take(2, "sensitivity direction")
    weight = r.take(6, "transducer weight")
    polarity = r.take(1, "polarity")
    transfer_function = None
    if r.take(1, "transfer-function flag"):
        transfer_function = TransferFunction(
            **{name: r.take(width, name) for name, width in TransferFunction.WIDTHS}
        )
    return AccelerometerTeds(
        sensitivity_code=sensitivity,
        high_pass_code=high_pass,
        direction=direction,
        weight_code=weight,
        polarity=polarity,
        transfer_function=transfer_function,
        reference_frequency_code=r.take(8, "reference frequency"),
        reference_temperature_code=r.take(5, "reference temperature"),
        calibration_date_code=r.take(16, "calibration date"),
        calibration_initials_codes=(
            r.take(5, "calibration initials"),
            r.take(5, "calibration initials"),
            r.take(5, "calibration initials"),
        ),
        calibration_period_days=r.take(12, "calibration period"),
        measurement_location_id=r.take(11, "measurement location id"),
    )


def encode(teds: Teds) -> tuple[int, ...]:
    """The bits of a TEDS, transmission order (the inverse of `decode`)."""
    out: list[int] = []
    for name, width in BasicTeds.WIDTHS:
        _put(out, getattr(teds.basic, name), width, name)
    _put(out, teds.selector, 2, "template selector")
    _put(out, teds.template_id, 8, "template id")
    a = teds.accelerometer
    if a is not None:
        if (teds.selector, teds.template_id) != (0, TEMPLATE_ACCELEROMETER):
            raise TedsError("template id: an accelerometer template needs selector 0, id 25")
        _put(out, 0, 1, "acceleration/force selector")
        _put(out, 0, 1, "extended functionality selector")
        _put(out, a.sensitivity_code, 16, "sensitivity")
        _put(out, a.high_pass_code, 8, "high-pass cut-off")
        _put(out, a.direction, 2, "sensitivity direction")
        _put(out, a.weight_code, 6, "transducer weight")
        _put(out, a.polarity, 1, "polarity")
        _put(out, int(a.transfer_function is not None), 1, "transfer-function flag")
        if a.transfer_function is not None:
            for name, width in TransferFunction.WIDTHS:
                _put(out, getattr(a.transfer_function, name), width, name)
        _put(out, a.reference_frequency_code, 8, "reference frequency")
        _put(out, a.reference_temperature_code, 5, "reference temperature")
        _put(out, a.calibration_date_code, 16, "calibration date")
        for code in a.calibration_initials_codes:
            _put(out, code, 5, "calibration initials")
        _put(out, a.calibration_period_days, 12, "calibration period")
        _put(out, a.measurement_location_id, 11, "measurement location id")
    out.extend(teds.trailing_bits)
    return tuple(out)


def bitstream_bytes(bits: tuple[int, ...]) -> bytes:
    """Bits packed LSB first into bytes, the last zero-padded (nidaqmx's teds_bit_stream)."""
    packed = bytearray((len(bits) + 7) // 8)
    for i, bit in enumerate(bits):
        packed[i // 8] |= bit << (i % 8)
    return bytes(packed)


def bits_from_bytes(data: bytes, count: int | None = None) -> tuple[int, ...]:
    """The bits of LSB-first packed bytes (the first `count`, default all)."""
    bits = tuple((byte >> i) & 1 for byte in data for i in range(8))
    return bits if count is None else bits[:count]


@dataclass(frozen=True)
class ChannelTeds:
    """One input channel's TEDS as read on its physical channel: the bytes (bits LSB first, as
    DAQmx's teds_bit_stream gives them), or `data` None and the reason there are none."""

    physical: str
    data: bytes | None
    reason: str = ""

    def __post_init__(self) -> None:
        if (self.data is None) != bool(self.reason):
            raise TedsError(
                f"TEDS of {self.physical}: either the bytes read or the reason there are none"
            )

    def bits(self) -> tuple[int, ...]:
        """The TEDS bits (transmission order, the last byte's padding included); TedsError
        with the reason when the channel gave none."""
        if self.data is None:
            raise TedsError(f"TEDS of {self.physical}: {self.reason}")
        return bits_from_bytes(self.data)

    def decoded(self) -> Teds:
        """The TEDS decoded (`decode`); TedsError naming the field, or the reason none."""
        return decode(self.bits())


def read_ted_file(path: str | Path) -> tuple[int, ...]:
    """The TEDS bits of an NI virtual-TEDS file (.ted: 40-bit header, then one bit per byte)."""
    path = Path(path)
    if not path.is_file():
        raise TedsError(f"{path}: not a file")
    if path.stat().st_size > len(TED_FILE_HEADER) + MAX_TEDS_BITS:
        raise TedsError(f"{path}: larger than any TEDS ({MAX_TEDS_BITS} bits)")
    data = path.read_bytes()
    if tuple(data[: len(TED_FILE_HEADER)]) != TED_FILE_HEADER:
        raise TedsError(f"{path}: no NI .ted header ([v03]) at the start")
    if any(b not in (0, 1) for b in data):
        raise TedsError(f"{path}: a .ted file holds one bit (0 or 1) per byte")
    return tuple(data[len(TED_FILE_HEADER) :])


def ted_file_bytes(bits: tuple[int, ...]) -> bytes:
    """The bytes of an NI .ted file holding `bits`."""
    return bytes(TED_FILE_HEADER) + bytes(bits)
