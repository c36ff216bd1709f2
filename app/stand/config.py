"""Stand configuration (`stand.toml`): validated on load, every error names its field.

Sections (units in the names):

    [laboratory]  name, address, accreditation (optional), verify_url (optional: the web view's
                  public /verify address the certificate's QR code leads to)
    [daq]         backend = "sim" | "nidaqmx", device, skew_s (DUT channel's sampling delay),
                  skew_tolerance_s (its tolerance, half-width: the phase term 360 f tau deg)
                  input_ranges_v (the +-ranges, V, its inputs offer; optional, else the
                  device's own list: each run picks per channel from the predicted peaks,
                  issue 32), adc_bits (16), adc_linearity_lsb (the converter's nonlinearity
                  near its codes, half-width in LSB, from its data sheet; 1)
    [daq.output]  physical, range_v
    [daq.reference] / [daq.dut] / [daq.drive] (optional loopback):
                  physical, range_v (the largest range the channel may use), coupling
                  ("dc"/"ac"), iepe_current_a, terminal
    [amplifiers]  measuring (VISA resource), reference_channel, power (VISA resource, optional)
    [limits]      displacement_peak_to_peak_m, velocity_peak_m_per_s, acceleration_peak_ms2,
                  drive_peak_v
    [reference]   id, model, serial, certificate_number, certificate_date, gain (conditioning,
                  V/V), frequencies_hz, sensitivity_mv_per_ms2, phase_deg (its certificate;
                  with the records in use the table comes from them, found by id or serial,
                  and a table here must be the same)
    [dut_channel] gain (V/V between DUT and DAQ)
    [[component]] the type B budget (dsp.uncertainty.Component fields, with `kind`: the
                  ISO 16063-21 Annex A component(s) it states, dsp.annex_a, and `law`,
                  `law_frequency_hz`, `law_exponent` for terms growing with frequency, or
                  `table`: [Hz, value] rows, one value per band, dsp.budget_table)
    [[cmc]]       the laboratory's CMC per band (dsp.cmc: min_frequency_hz, max_frequency_hz,
                  magnitude_percent, phase_deg); without it no PASS, no certificate (issue 32)
    [simulation]  simulated stand only: which components it draws its deviations from
    [[instrument]] role, model, serial, calibration_due, resource/driver (app.stand.instruments)

With no file, the built-in simulated stand (`sim/stand.toml`) is used.
"""

from __future__ import annotations

import difflib
import math
import tomllib
from dataclasses import dataclass, field, replace
from datetime import date
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from app.errors import Refusal
from app.io.checks import MAX_TEXT_BYTES, InputFileError, check_input_file
from app.io.vocabulary import Backend
from app.stand.exciters import parse_exciters
from app.stand.fixture import Fixture, FixtureError, parse_fixture
from app.stand.instruments import Instrument, InstrumentError, parse_instruments
from app.stand.schema import SCHEMA
from dsp.annex_a import implausible_components, missing_components
from dsp.budget_terms import skew_phase_component
from dsp.calibration import ReferenceChain
from dsp.cmc import Cmc
from dsp.resolution import Converter
from dsp.uncertainty import Budget
from hardware.interfaces import InputChannel, OutputChannel, input_ranges

BACKENDS = tuple(b.value for b in Backend)


class ConfigError(Refusal):
    """A stand configuration that cannot be used; the message names the file and field."""


def check_verify_url(verify_url: str) -> str:
    """`verify_url` without a trailing slash; ConfigError unless it is an absolute http(s)
    address with no ?query or #fragment (a certificate number and code are appended to it)."""
    parts = urlsplit(verify_url.strip())
    if parts.scheme not in ("http", "https") or not parts.netloc:
        raise ConfigError(f"not an http(s) address: {verify_url!r}")
    if parts.query or parts.fragment:
        raise ConfigError(f"must have no ?query or #fragment: {verify_url!r}")
    return verify_url.strip().rstrip("/")


@dataclass(frozen=True)
class Limits:
    """What the exciter and amplifier may be asked for (peaks)."""

    displacement_peak_to_peak_m: float
    velocity_peak_m_per_s: float
    acceleration_peak_ms2: float
    drive_peak_v: float


@dataclass(frozen=True)
class StandPlan:
    """A stand file's [plan]: lines (Hz), sample rate (Hz), period (samples), reference
    frequency (Hz), amplitude profile and its corner (Hz); None: the preset's or the run's."""

    frequencies_hz: tuple[float, ...] | None = None
    sample_rate_hz: float | None = None
    period_samples: int | None = None
    reference_frequency_hz: float | None = None
    profile: str | None = None
    corner_hz: float | None = None


@dataclass(frozen=True)
class ReferenceStandard:
    """Identity and certificate of the reference standard (sensitivity table optional for the
    simulated stand, which issues its own)."""

    id: str
    model: str
    serial: str
    certificate_number: str
    certificate_date: str
    gain: float
    frequencies_hz: tuple[float, ...] = ()
    sensitivity_mv_per_ms2: tuple[float, ...] = ()
    phase_deg: tuple[float, ...] = ()
    # where the certificate and table come from when not this file: "records" (then with
    # the certificate's due date, ISO 8601); "" for the stand file (or the simulated stand)
    table_from: str = ""
    due_date: str = ""
    # the reference DCC the records' table was read from (issue 35 point 4): its
    # uniqueIdentifier, calibrating laboratory and SHA-256; "" when none
    dcc_identifier: str = ""
    dcc_laboratory: str = ""
    dcc_sha256: str = ""


@dataclass(frozen=True)
class StandConfig:
    """A whole stand: where things are, what they may do, and what is known about them."""

    source: str
    laboratory: dict[str, str]
    backend: Backend
    device: str
    skew_s: float
    output: OutputChannel
    inputs: tuple[InputChannel, ...]
    measuring_amplifier: str | None
    reference_amplifier_channel: int
    power_amplifier: str | None
    limits: Limits
    reference: ReferenceStandard
    dut_gain: float
    budget: Budget
    simulation: dict[str, str] = field(default_factory=dict)
    plan: StandPlan = field(default_factory=StandPlan)
    cmc: Cmc | None = None  # the laboratory's CMC ([[cmc]]); None: none stated
    # [exciters.<name>] [[component]]: the simulated exciters' own terms (app.stand.exciters)
    exciter_components: dict[str, Budget] = field(default_factory=dict)
    # the +-ranges (V) the inputs offer, as the stand file states them (() : the device's own)
    input_ranges_v: tuple[float, ...] = ()
    converter: Converter = field(default_factory=Converter)
    instruments: tuple[Instrument, ...] = ()  # [[instrument]]: DAQ, amplifiers, sensor
    # [fixture]: the positions of several DUTs in one run (app.stand.fixture); None: one DUT
    fixture: Fixture | None = None
    raw: dict[str, Any] = field(default_factory=dict, repr=False)
    text: str = field(default="", repr=False)  # the stand file as read (copied into each run)

    def missing_components(self) -> list[str]:
        """ISO 16063-21 Annex A components the stand's budget does not state (dsp.annex_a);
        empty for a full budget. A run on a stand with any missing is for review only."""
        return missing_components(self.budget)

    def with_reference_certificate(
        self,
        certificate_number: str,
        certificate_date: str,
        frequencies_hz: tuple[float, ...],
        sensitivity_mv_per_ms2: tuple[float, ...],
        phase_deg: tuple[float, ...],
        *,
        due_date: str,
        table_from: str = "records",
        dcc: tuple[str, str, str] = ("", "", ""),
    ) -> StandConfig:
        """This stand with its reference standard's certificate (number, dates ISO 8601) and
        table (Hz, mV/(m/s^2), degrees) taken from `table_from` (the records), read from the
        reference DCC `dcc` (uniqueIdentifier, laboratory, SHA-256; blank: none). ConfigError
        when the table is not a usable certificate table."""
        try:
            ReferenceChain(frequencies_hz, sensitivity_mv_per_ms2, phase_deg)
        except ValueError as exc:
            raise ConfigError(f"reference table: {exc}") from None
        reference = replace(
            self.reference,
            certificate_number=certificate_number,
            certificate_date=certificate_date,
            frequencies_hz=tuple(frequencies_hz),
            sensitivity_mv_per_ms2=tuple(sensitivity_mv_per_ms2),
            phase_deg=tuple(phase_deg),
            table_from=table_from,
            due_date=due_date,
            dcc_identifier=dcc[0],
            dcc_laboratory=dcc[1],
            dcc_sha256=dcc[2],
        )
        return replace(self, reference=reference)

    def reference_chain(self) -> ReferenceChain:
        """The chain the analysis uses: the certificate, nominal gains and the skew."""
        ref = self.reference
        if not ref.frequencies_hz:
            raise ConfigError(
                f"{self.source}: reference.frequencies_hz: no certificate table (give it here, "
                "or keep the reference standard in the records and use them: --db)"
            )
        return ReferenceChain(
            ref.frequencies_hz,
            ref.sensitivity_mv_per_ms2,
            ref.phase_deg,
            reference_gain=ref.gain,
            dut_gain=self.dut_gain,
            skew_s=self.skew_s,
        )


class _Reader:
    """Typed access to nested TOML tables with errors naming `section.key`."""

    def __init__(self, data: dict[str, Any], source: str):
        self.data = data
        self.source = source

    def fail(self, where: str, why: str) -> ConfigError:
        return ConfigError(f"{self.source}: {where}: {why}")

    def table(self, path: str, required: bool = True) -> dict[str, Any]:
        node: Any = self.data
        for part in path.split("."):
            if not isinstance(node, dict) or part not in node:
                if required:
                    raise self.fail(path, "missing section")
                return {}
            node = node[part]
        if not isinstance(node, dict):
            raise self.fail(path, "must be a table")
        return node

    def value(
        self, table: dict[str, Any], path: str, key: str, kind: type, default: Any = ...
    ) -> Any:
        where = f"{path}.{key}"
        if key not in table:
            if default is ...:
                raise self.fail(where, "missing")
            return default
        value = table[key]
        if kind is float:
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise self.fail(where, f"must be a number, got {value!r}")
            value = float(value)
            if not math.isfinite(value):
                raise self.fail(where, "must be finite")
        elif kind is int:
            if isinstance(value, bool) or not isinstance(value, int):
                raise self.fail(where, f"must be an integer, got {value!r}")
        elif kind is str:
            if isinstance(value, date):
                value = value.isoformat()
            if not isinstance(value, str) or not value.strip():
                raise self.fail(where, f"must be a non-empty string, got {value!r}")
        return value

    def positive(self, table: dict[str, Any], path: str, key: str, default: Any = ...) -> float:
        value = self.value(table, path, key, float, default)
        if not value > 0:
            raise self.fail(f"{path}.{key}", f"must be > 0, got {value:g}")
        return value

    def floats(self, table: dict[str, Any], path: str, key: str) -> tuple[float, ...]:
        values = table.get(key, [])
        if not isinstance(values, list) or not all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in values
        ):
            raise self.fail(f"{path}.{key}", "must be a list of numbers")
        return tuple(float(v) for v in values)


def _channel(r: _Reader, name: str, required: bool = True) -> InputChannel | None:
    path = f"daq.{name}"
    t = r.table(path, required)
    if not t:
        return None
    coupling = r.value(t, path, "coupling", str, "dc")
    if coupling not in ("dc", "ac"):
        raise r.fail(f"{path}.coupling", f"must be 'dc' or 'ac', got {coupling!r}")
    terminal = r.value(t, path, "terminal", str, "default")
    try:
        return InputChannel(
            name,  # type: ignore[arg-type]
            r.value(t, path, "physical", str),
            r.positive(t, path, "range_v"),
            coupling,  # type: ignore[arg-type]
            r.value(t, path, "iepe_current_a", float, 0.0),
            terminal,  # type: ignore[arg-type]
        )
    except ValueError as exc:
        raise r.fail(path, str(exc)) from None


def _unknown_key(data: dict[str, Any]) -> str | None:
    """The first key not in SCHEMA, named with the nearest known key; None when all are known."""
    for path, known in SCHEMA.items():
        table: Any = data
        for part in path.split(".") if path else ():
            table = table.get(part) if isinstance(table, dict) else None
        if not isinstance(table, dict):
            continue
        for key in table:
            if key in known:
                continue
            where = f"{path}.{key}" if path else key
            close = difflib.get_close_matches(key, sorted(known), n=1, cutoff=0.5)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            return f"{where}: unknown key{hint}"
    return None


def _distinct_channels(inputs: tuple[InputChannel, ...], r: _Reader) -> None:
    """ConfigError when two input channels name the same physical channel (the DUT would be
    compared with itself, or with the drive)."""
    seen: dict[str, str] = {}
    for channel in inputs:
        physical = channel.physical.strip().lower()
        if physical in seen:
            raise r.fail(
                f"daq.{channel.name}.physical",
                f"{channel.physical!r} is also daq.{seen[physical]}.physical; each input "
                "needs its own physical channel",
            )
        seen[physical] = channel.name


def parse(text: str, source: str) -> StandConfig:
    """Parse and validate a stand configuration given as TOML text. An unknown key is refused,
    and named beside any other error (a misspelt key is usually why one is missing)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: not valid TOML: {exc}") from None
    try:
        config = _parse(data, text, source)
    except ConfigError as exc:
        unknown = _unknown_key(data)
        if unknown:
            raise ConfigError(f"{exc}; and {unknown}") from None
        raise
    unknown = _unknown_key(data)
    if unknown:
        raise ConfigError(f"{source}: {unknown}")
    return config


def _parse(data: dict[str, Any], text: str, source: str) -> StandConfig:
    r = _Reader(data, source)
    lab = r.table("laboratory")
    laboratory = {
        "name": r.value(lab, "laboratory", "name", str),
        "address": r.value(lab, "laboratory", "address", str),
        "accreditation": lab.get("accreditation", ""),
        "country": lab.get("country", ""),
    }
    if not isinstance(laboratory["accreditation"], str):
        raise r.fail("laboratory.accreditation", "must be a string (may be empty)")
    country = laboratory["country"]
    if country and not (
        isinstance(country, str) and len(country) == 2 and country.isascii() and country.isupper()
    ):
        raise r.fail(
            "laboratory.country", f"an ISO 3166-1 two-letter code like 'PL', got {country!r}"
        )
    if "verify_url" in lab:  # only when given: the stored [laboratory] of other stands is as before
        url = lab["verify_url"]
        if not isinstance(url, str):
            raise r.fail("laboratory.verify_url", "must be a string")
        try:
            laboratory["verify_url"] = check_verify_url(url)
        except ConfigError as exc:
            raise r.fail("laboratory.verify_url", str(exc)) from None
    daq = r.table("daq")
    backend = r.value(daq, "daq", "backend", str)
    if backend not in BACKENDS:
        raise r.fail("daq.backend", f"must be one of {', '.join(BACKENDS)}, got {backend!r}")
    out = r.table("daq.output")
    output = OutputChannel(
        r.value(out, "daq.output", "physical", str), r.positive(out, "daq.output", "range_v")
    )
    inputs = tuple(
        c for c in (_channel(r, "reference"), _channel(r, "dut"), _channel(r, "drive", False)) if c
    )
    _distinct_channels(inputs, r)
    try:
        fixture = parse_fixture(
            data,
            next((c for c in inputs if c.name == "dut"), None),
            {c.physical: c.name for c in inputs},
        )
    except FixtureError as exc:
        raise ConfigError(f"{r.source}: {exc}") from None
    offered, converter = _converter(r, daq)
    skew = r.value(daq, "daq", "skew_s", float, 0.0)
    if not 0 <= skew < 1e-3:
        raise r.fail("daq.skew_s", f"must be between 0 and 1 ms, got {skew:g} s")
    amps = r.table("amplifiers", required=False)
    lim = r.table("limits")
    limits = Limits(
        r.positive(lim, "limits", "displacement_peak_to_peak_m"),
        r.positive(lim, "limits", "velocity_peak_m_per_s"),
        r.positive(lim, "limits", "acceleration_peak_ms2"),
        r.positive(lim, "limits", "drive_peak_v"),
    )
    if limits.drive_peak_v > output.range_v:
        raise r.fail("limits.drive_peak_v", f"exceeds the output range {output.range_v:g} V")
    ref = r.table("reference")
    reference = ReferenceStandard(
        id=r.value(ref, "reference", "id", str),
        model=r.value(ref, "reference", "model", str),
        serial=r.value(ref, "reference", "serial", str),
        certificate_number=r.value(ref, "reference", "certificate_number", str),
        certificate_date=r.value(ref, "reference", "certificate_date", str),
        gain=r.positive(ref, "reference", "gain", 1.0),
        frequencies_hz=r.floats(ref, "reference", "frequencies_hz"),
        sensitivity_mv_per_ms2=r.floats(ref, "reference", "sensitivity_mv_per_ms2"),
        phase_deg=r.floats(ref, "reference", "phase_deg"),
    )
    table_given = (
        reference.frequencies_hz or reference.sensitivity_mv_per_ms2 or reference.phase_deg
    )
    if table_given:  # without one: the simulated stand's own, or the records' (checked on use)
        try:
            ReferenceChain(
                reference.frequencies_hz,
                reference.sensitivity_mv_per_ms2,
                reference.phase_deg or (0.0,) * len(reference.frequencies_hz),
            )
        except ValueError as exc:
            raise r.fail("reference", str(exc).replace("reference chain: ", "")) from None
        if not reference.phase_deg:
            reference = ReferenceStandard(
                **{**reference.__dict__, "phase_deg": (0.0,) * len(reference.frequencies_hz)}
            )
    dut_channel = r.table("dut_channel", required=False)
    try:
        budget = Budget.from_list(data.get("component", []))
    except ValueError as exc:
        raise r.fail("component", str(exc)) from None
    if "skew_tolerance_s" in daq:
        tolerance = r.value(daq, "daq", "skew_tolerance_s", float)
        try:
            skew_term = skew_phase_component(tolerance)
        except ValueError as exc:
            raise r.fail("daq.skew_tolerance_s", str(exc).replace("skew tolerance: ", "")) from None
        if any(c.name == skew_term.name for c in budget.components):
            raise r.fail("daq.skew_tolerance_s", f"a component is already named {skew_term.name!r}")
        budget = Budget((*budget.components, skew_term))
    refused = implausible_components(budget)
    if refused:
        raise r.fail("component", f"refused: {'; '.join(refused)}")
    cmc = _cmc(r, data)
    simulation = data.get("simulation", {})
    if backend != Backend.SIM and simulation:
        raise r.fail("simulation", "only for the simulated stand (daq.backend = 'sim')")
    try:
        exciters = parse_exciters(data, simulated=backend == Backend.SIM)
    except ValueError as exc:
        raise ConfigError(f"{r.source}: {exc}") from None
    try:
        instruments = parse_instruments(data.get("instrument"))
    except InstrumentError as exc:
        raise ConfigError(f"{r.source}: {exc}") from None
    measuring = amps.get("measuring")
    power = amps.get("power")
    for key, value in (("measuring", measuring), ("power", power)):
        if value is not None and (not isinstance(value, str) or not value.strip()):
            raise r.fail(f"amplifiers.{key}", "must be a VISA resource name")
    return StandConfig(
        source=source,
        laboratory=laboratory,
        backend=Backend(backend),
        device=r.value(daq, "daq", "device", str, "sim"),
        skew_s=skew,
        output=output,
        inputs=inputs,
        measuring_amplifier=measuring,
        reference_amplifier_channel=r.value(amps, "amplifiers", "reference_channel", int, 1),
        power_amplifier=power,
        limits=limits,
        reference=reference,
        dut_gain=r.positive(dut_channel, "dut_channel", "gain", 1.0),
        budget=budget,
        # [simulation.fixture] is the simulated fixture's physics (sim.fixture), not a target
        simulation={k: v for k, v in simulation.items() if k != "fixture"},
        plan=_plan(r),
        cmc=cmc,
        exciter_components=exciters,
        input_ranges_v=offered,
        converter=converter,
        instruments=instruments,
        fixture=fixture,
        raw=data,
        text=text,
    )


def _cmc(r: _Reader, data: dict[str, Any]) -> Cmc | None:
    """[[cmc]] as a Cmc (a ConfigError naming the entry and key); None when absent."""
    entries = data.get("cmc")
    try:
        if entries is not None and not isinstance(entries, list):
            raise ValueError("must be an array of tables ([[cmc]])")
        return None if entries is None else Cmc.from_list(entries)
    except ValueError as exc:
        raise r.fail("cmc", str(exc)) from None


def _converter(r: _Reader, daq: dict[str, Any]) -> tuple[tuple[float, ...], Converter]:
    """[daq] input_ranges_v, adc_bits, adc_linearity_lsb (ConfigError naming daq.<key>)."""
    offered: tuple[float, ...] = ()
    if "input_ranges_v" in daq:
        try:
            offered = input_ranges(daq["input_ranges_v"], "daq.input_ranges_v")
        except ValueError as exc:
            raise r.fail("daq.input_ranges_v", str(exc).split(": ", 1)[-1]) from None
    bits = r.value(daq, "daq", "adc_bits", int, 16)
    linearity = r.value(daq, "daq", "adc_linearity_lsb", float, 1.0)
    try:
        converter = Converter(bits, linearity)
    except ValueError as exc:
        key = "adc_bits" if "bits" in str(exc) else "adc_linearity_lsb"
        raise r.fail(f"daq.{key}", str(exc).split(": ", 1)[-1]) from None
    return offered, converter


def _plan(r: _Reader) -> StandPlan:
    """[plan], each value checked (a ConfigError naming plan.<key>)."""
    t = r.table("plan", required=False)
    if not t:
        return StandPlan()
    freqs = r.floats(t, "plan", "frequencies_hz") if "frequencies_hz" in t else None
    if freqs is not None and not (freqs and all(math.isfinite(f) and f > 0 for f in freqs)):
        raise r.fail("plan.frequencies_hz", "must be a non-empty list of numbers > 0 Hz")
    period = r.value(t, "plan", "period_samples", int, None)
    if period is not None and not 4 <= period <= 2**24:
        raise r.fail("plan.period_samples", f"must be in [4, 16777216], got {period}")
    profile = r.value(t, "plan", "profile", str, None)
    if profile is not None and profile not in ("acceleration", "velocity", "displacement"):
        raise r.fail(
            "plan.profile", f"one of acceleration, velocity, displacement, got {profile!r}"
        )

    def optional(key: str) -> float | None:
        return r.positive(t, "plan", key, None) if key in t else None

    return StandPlan(
        freqs,
        optional("sample_rate_hz"),
        period,
        optional("reference_frequency_hz"),
        profile,
        optional("corner_hz"),
    )


def load(path: str | Path | None = None) -> StandConfig:
    """Load `path`, or the built-in simulated stand when None."""
    if path is None:
        text = resources.files("sim").joinpath("stand.toml").read_text(encoding="utf-8")
        return parse(text, "built-in simulated stand")
    path = Path(path)
    try:
        check_input_file(path, MAX_TEXT_BYTES, "stand file")
    except InputFileError as exc:
        raise ConfigError(str(exc)) from None
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot be read ({exc})") from None
    return parse(text, str(path))
