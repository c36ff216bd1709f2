"""NiDaq with one reference, several DUT channels and the drive read-back in one AI task (issue 36
point 5), against a recording fake of DAQmx: the channel strings and every call byte-exact, the
skews from the convert rate, a read of scan-interleaved samples through nidaqmx's own
AnalogMultiChannelReader de-multiplexed to the right channel names, TEDS per channel, and the
refusals naming the channel. No NI hardware or driver needed."""

from __future__ import annotations

import threading
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import nidaqmx.errors
import numpy as np
import pytest
from nidaqmx.constants import (
    AcquisitionType,
    Coupling,
    ExcitationSource,
    FillMode,
    RegenerationMode,
    TerminalConfiguration,
)

from hardware import nidaq
from hardware.errors import DaqNotFoundError, DeviceLostError, HardwareError, InputRefused
from hardware.interfaces import (
    DaqConfig,
    DaqStatus,
    InputChannel,
    OutputChannel,
    is_dut_channel,
)
from hardware.nidaq import NiDaq, read_teds_channels
from hardware.teds import ChannelTeds, TedsError, bitstream_bytes, decode, read_ted_file

FS = 51_200.0
ACTUAL_FS = 51_200.0
CONV_RATE = 250_000.0  # a multiplexed board: one conversion every 4 us
N = 64

#: 1 reference + 4 DUT channels + the drive read-back; the physical inputs deliberately not in
#: the order of the names, so that a read that ignores the task's channel order shows
INPUTS = (
    InputChannel("reference", "Dev1/ai0", 10.0, terminal="differential"),
    InputChannel(
        "dut.A", "Dev1/ai4", 1.0, coupling="ac", iepe_current_a=0.004, terminal="pseudodifferential"
    ),
    InputChannel("dut.B", "Dev1/ai2", 2.0, coupling="ac", iepe_current_a=0.002),
    InputChannel("dut.C", "Dev1/ai6", 5.0),  # dc, no IEPE: a capacitive MEMS sensor
    InputChannel("dut.D-2", "Dev1/ai3", 0.5, iepe_current_a=0.01, terminal="rse"),
    InputChannel("drive", "Dev1/ai7", 2.0, terminal="rse"),
)
CONFIG = DaqConfig(FS, N, OutputChannel("Dev1/ao0", 5.0), INPUTS)
DATA = Path(__file__).resolve().parents[1] / "data" / "teds"


def daq_error(code: int, message: str = "scripted DAQmx error") -> nidaqmx.errors.DaqError:
    return nidaqmx.errors.DaqError(message, code)


class Recorder:
    """An object whose attribute assignments are recorded as (who.attribute, value)."""

    def __init__(self, who: str, events: list[tuple[Any, ...]]) -> None:
        object.__setattr__(self, "_who", who)
        object.__setattr__(self, "_events", events)

    def __setattr__(self, name: str, value: Any) -> None:
        self._events.append((f"{self._who}.{name}", value))
        object.__setattr__(self, name, value)


class Interpreter:
    """DAQmx's read as the C library does it: the board delivers scans (one sample of every
    channel of the task, in the task's order); DAQmxReadAnalogF64 hands them out grouped by
    channel or by scan, as asked. Sample s of the channel on physical input aiK reads
    K + s / 1e6 V (s counts from the task's start)."""

    def __init__(self, task: FakeTask) -> None:
        self.task = task
        self.scans = 0
        self.fill_modes: list[int] = []

    def read_analog_f64(self, handle, n, timeout, fill_mode, data):
        inputs = [int(p.rsplit("ai", 1)[1]) for p in self.task.physical]
        s = self.scans + np.arange(n)
        scans = np.array(inputs)[None, :] + s[:, None] / 1e6  # (n, channels): scan order
        self.scans += n
        self.fill_modes.append(fill_mode)
        if fill_mode == FillMode.GROUP_BY_CHANNEL.value:
            data[:] = scans.T
        else:
            data.reshape(-1)[:] = scans.reshape(-1)  # interleaved, as the board sent them
        return data, n


class FakeTiming:
    """A task's timing: the sample clock as configured, the convert rate (or the error DAQmx
    raises for it on a simultaneous-sampling board); calls appended to `events`."""

    def __init__(self, who: str, events: list[tuple[Any, ...]], conv: float | Exception) -> None:
        self.who, self.events, self.conv = who, events, conv
        self.samp_clk_rate = 0.0

    def cfg_samp_clk_timing(self, rate, **kwargs):
        self.events.append((f"{self.who}.cfg_samp_clk_timing", rate, kwargs))
        self.samp_clk_rate = ACTUAL_FS

    @property
    def ai_conv_rate(self) -> float:
        self.events.append((f"{self.who}.ai_conv_rate",))
        if isinstance(self.conv, Exception):
            raise self.conv
        return self.conv


class FakeTask:
    """nidaqmx.Task as far as NiDaq goes (`who`: "ai" or "ao"); every call appended to
    `events`; the AI task's in_stream reads through `Interpreter`."""

    def __init__(self, who: str, events: list[tuple[Any, ...]], conv: float | Exception) -> None:
        self.who, self.events = who, events
        self.physical: list[str] = []
        self.timing = FakeTiming(who, events, conv)
        self.ai_channels = SimpleNamespace(add_ai_voltage_chan=self._add_ai)
        self.ao_channels = SimpleNamespace(add_ao_voltage_chan=self._add_ao)
        self.triggers = SimpleNamespace(
            start_trigger=SimpleNamespace(cfg_dig_edge_start_trig=self._trig)
        )
        self.out_stream = Recorder(f"{who}.out_stream", events)
        self.interpreter = Interpreter(self)
        task = SimpleNamespace(
            _handle=f"{who}-handle",
            _interpreter=self.interpreter,
            _calculate_num_samps_per_chan=lambda n: n,
        )
        self.in_stream = SimpleNamespace(_task=task, num_chans=0)

    def _add_ai(self, physical, **kwargs):
        self.events.append((f"{self.who}.add_ai_voltage_chan", physical, kwargs))
        self.physical.append(physical)
        self.in_stream.num_chans = len(self.physical)
        return Recorder(physical, self.events)

    def _add_ao(self, physical, **kwargs):
        self.events.append((f"{self.who}.add_ao_voltage_chan", physical, kwargs))

    def _trig(self, source):
        self.events.append((f"{self.who}.cfg_dig_edge_start_trig", source))

    def write(self, data, auto_start, timeout=None):
        self.events.append((f"{self.who}.write", "period" if np.any(data) else "zeros"))

    def start(self):
        self.events.append((f"{self.who}.start",))

    def stop(self):
        self.events.append((f"{self.who}.stop",))

    def close(self):
        self.events.append((f"{self.who}.close",))


class Factory:
    """Makes the AI task, then the AO task (NiDaq's order), sharing one event list."""

    def __init__(self, conv: float | Exception = CONV_RATE) -> None:
        self.events: list[tuple[Any, ...]] = []
        self.conv = conv
        self.tasks: list[FakeTask] = []

    def __call__(self) -> FakeTask:
        task = FakeTask(("ai", "ao")[len(self.tasks) % 2], self.events, self.conv)
        self.tasks.append(task)
        return task


@pytest.fixture
def factory(monkeypatch) -> Factory:
    monkeypatch.setattr(nidaq, "_sleep", lambda s: None)
    return Factory()


def test_one_ai_task_holds_every_channel_with_its_settings_and_one_sample_clock(factory):
    daq = NiDaq("Dev1", task_factory=factory)
    status = daq.configure(CONFIG)
    diff, pseudo, default, rse = (
        TerminalConfiguration.DIFF,
        TerminalConfiguration.PSEUDO_DIFF,
        TerminalConfiguration.DEFAULT,
        TerminalConfiguration.RSE,
    )

    def ai(physical: str, range_v: float, terminal: TerminalConfiguration) -> tuple[Any, ...]:
        kwargs = dict(min_val=-range_v, max_val=range_v, terminal_config=terminal)
        return ("ai.add_ai_voltage_chan", physical, kwargs)

    assert factory.events == [
        ai("Dev1/ai0", 10.0, diff),
        ai("Dev1/ai4", 1.0, pseudo),
        ("Dev1/ai4.ai_coupling", Coupling.AC),
        ("Dev1/ai4.ai_excit_src", ExcitationSource.INTERNAL),
        ("Dev1/ai4.ai_excit_val", 0.004),
        ai("Dev1/ai2", 2.0, default),
        ("Dev1/ai2.ai_coupling", Coupling.AC),
        ("Dev1/ai2.ai_excit_src", ExcitationSource.INTERNAL),
        ("Dev1/ai2.ai_excit_val", 0.002),
        ai("Dev1/ai6", 5.0, default),
        ai("Dev1/ai3", 0.5, rse),
        ("Dev1/ai3.ai_excit_src", ExcitationSource.INTERNAL),  # dc coupled, IEPE on
        ("Dev1/ai3.ai_excit_val", 0.01),
        ai("Dev1/ai7", 2.0, rse),
        ("ao.add_ao_voltage_chan", "Dev1/ao0", dict(min_val=-5.0, max_val=5.0)),
        (
            "ai.cfg_samp_clk_timing",
            FS,
            dict(sample_mode=AcquisitionType.CONTINUOUS, samps_per_chan=4 * N),
        ),
        (
            "ao.cfg_samp_clk_timing",
            ACTUAL_FS,
            dict(
                source="/Dev1/ai/SampleClock",
                sample_mode=AcquisitionType.CONTINUOUS,
                samps_per_chan=N,
            ),
        ),
        ("ao.cfg_dig_edge_start_trig", "/Dev1/ai/StartTrigger"),
        ("ao.out_stream.regen_mode", RegenerationMode.ALLOW_REGENERATION),
        ("ai.ai_conv_rate",),
    ]  # fmt: skip
    assert len(factory.tasks) == 2  # one AI task for all six inputs, one AO task
    assert status.actual_sample_rate_hz == ACTUAL_FS
    # channel k of the task is converted k / 250 kHz = k * 4 us after the first
    assert dict(status.skews_s) == pytest.approx(
        {"reference": 0.0, "dut.A": 4e-6, "dut.B": 8e-6, "dut.C": 12e-6, "dut.D-2": 16e-6,
         "drive": 20e-6},
        rel=1e-12,
    )  # fmt: skip
    assert list(status.skews_s) == [c.name for c in INPUTS]
    assert status.skew_s == pytest.approx(4e-6, rel=1e-12)  # the first DUT channel's
    daq.stop()


def test_skews_are_counted_from_the_reference_wherever_it_is_and_zero_without_convert_clock(
    monkeypatch,
):
    monkeypatch.setattr(nidaq, "_sleep", lambda s: None)
    order = (INPUTS[3], INPUTS[2], INPUTS[0], INPUTS[5], INPUTS[1])  # C, B, reference, drive, A
    config = DaqConfig(FS, N, CONFIG.output, order)
    status = NiDaq("Dev1", task_factory=Factory()).configure(config)
    assert dict(status.skews_s) == pytest.approx(
        {"dut.C": -8e-6, "dut.B": -4e-6, "reference": 0.0, "drive": 4e-6, "dut.A": 8e-6},
        rel=1e-12,
    )
    assert status.skew_s == pytest.approx(-8e-6, rel=1e-12)  # dut.C: the first DUT in the task

    simultaneous = Factory(conv=daq_error(-200452, "Specified property is not supported"))
    status = NiDaq("Dev1", task_factory=simultaneous).configure(CONFIG)
    assert status == DaqStatus(ACTUAL_FS, 0.0, dict.fromkeys([c.name for c in INPUTS], 0.0))


def test_a_single_dut_config_reports_as_before_with_every_skew_filled():
    config = DaqConfig(
        FS,
        N,
        CONFIG.output,
        (
            InputChannel("reference", "Dev1/ai0", 10.0),
            InputChannel("drive", "Dev1/ai3", 2.0),
            InputChannel("dut", "Dev1/ai1", 1.0),
        ),
    )
    status = NiDaq("Dev1", task_factory=Factory()).configure(config)
    assert status.skew_s == pytest.approx(2 / CONV_RATE, rel=1e-12)
    assert dict(status.skews_s) == pytest.approx(
        {"reference": 0.0, "drive": 1 / CONV_RATE, "dut": 2 / CONV_RATE}, rel=1e-12
    )


def test_interleaved_scans_come_back_per_channel_name_in_config_order(factory):
    """nidaqmx's own AnalogMultiChannelReader over a DAQmx read that knows both fill modes:
    the driver must ask for GROUP_BY_CHANNEL into a (channels, N) array, and every row must be
    the samples of the physical input its config entry names."""
    daq = NiDaq("Dev1", task_factory=factory)
    daq.configure(CONFIG)
    daq.start(np.sin(2 * np.pi * np.arange(N) / N))
    try:
        first = daq.read_period(timeout_s=5.0)
        second = daq.read_period(timeout_s=5.0)
    finally:
        daq.stop()
    assert first.shape == (6, N) and first.dtype == np.float64
    samples = np.arange(N) / 1e6
    by_name = dict(zip([c.name for c in INPUTS], first, strict=True))
    expected = {"reference": 0, "dut.A": 4, "dut.B": 2, "dut.C": 6, "dut.D-2": 3, "drive": 7}
    for name, physical in expected.items():
        np.testing.assert_array_equal(by_name[name], physical + samples, err_msg=name)
    np.testing.assert_array_equal(second[1], 4 + (N + np.arange(N)) / 1e6)  # the next period
    interpreter = factory.tasks[0].interpreter
    assert set(interpreter.fill_modes) == {FillMode.GROUP_BY_CHANNEL.value}


def test_the_fake_read_would_show_a_scan_ordered_read():
    """The check above can fail: the same samples grouped by scan are not the channels."""
    task = FakeTask("ai", [], CONV_RATE)
    for channel in INPUTS:
        task.ai_channels.add_ai_voltage_chan(channel.physical)
    data = np.zeros((6, N))
    task.interpreter.read_analog_f64("h", N, 1.0, FillMode.GROUP_BY_SCAN_NUMBER.value, data)
    assert not np.array_equal(data[1], 4 + np.arange(N) / 1e6)
    assert data[0, :6].tolist() == [0.0, 4.0, 2.0, 6.0, 3.0, 7.0]  # the first scan


# --- refusals, before any device is touched ---------------------------------------------------


def _with(*changed: InputChannel) -> DaqConfig:
    return DaqConfig(FS, N, CONFIG.output, (*INPUTS, *changed))


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (
            InputChannel("dut.E", "Dev1/ai4", 1.0),
            "NI-DAQ Dev1: input channels 'dut.A' and 'dut.E' are both on physical channel "
            "'Dev1/ai4'; each input needs its own",
        ),
        (
            InputChannel("dut.E", "dev1/AI2", 1.0),  # DAQmx names are case-insensitive
            "NI-DAQ Dev1: input channels 'dut.B' and 'dut.E' are both on physical channel "
            "'dev1/AI2'; each input needs its own",
        ),
        (
            InputChannel("dut.E", "/Dev1/ai0", 1.0),
            "NI-DAQ Dev1: input channels 'reference' and 'dut.E' are both on physical channel "
            "'/Dev1/ai0'; each input needs its own",
        ),
        (
            InputChannel("dut.E", "Dev1/ai8:9", 1.0),
            "NI-DAQ Dev1: input channel 'dut.E': physical channel 'Dev1/ai8:9' must name one "
            "input, e.g. 'Dev1/ai1'",
        ),
        (
            InputChannel("dut.E", "Dev1/ai8,Dev1/ai9", 1.0),
            "NI-DAQ Dev1: input channel 'dut.E': physical channel 'Dev1/ai8,Dev1/ai9' must name "
            "one input, e.g. 'Dev1/ai1'",
        ),
    ],
)
def test_a_physical_input_used_twice_or_naming_several_is_refused_naming_the_channels(
    extra, message
):
    made: list[Any] = []
    with pytest.raises(InputRefused) as info:
        NiDaq("Dev1", task_factory=lambda: made.append(1)).configure(_with(extra))
    assert str(info.value) == message
    assert made == []  # no task was created


@pytest.mark.parametrize(
    "name",
    [
        "dut.A.x.y",
        "dut.",
        "dut.A B",
        "dut.ABCDEFGHIJKLMNOPQ",
        "DUT.A",
        "dut_A",
        "monitor",
        "dut.A.",
        "dut.A\n",  # fullmatch: "$" would take a name with a newline
        "reference.A",
    ],
)
def test_a_channel_name_that_is_no_dut_reference_or_drive_is_refused_naming_it(name):
    assert not is_dut_channel(name)
    made: list[Any] = []
    with pytest.raises(InputRefused) as info:
        NiDaq("Dev1", task_factory=lambda: made.append(1)).configure(
            _with(InputChannel(name, "Dev1/ai9", 1.0))
        )
    assert str(info.value) == (
        f"NI-DAQ Dev1: input channel {name!r}: not a channel name ('reference', 'drive', 'dut', "
        "'dut.<position>' or 'dut.<position>.<axis>'; a position or axis is 1-16 of A-Z a-z "
        "0-9 _ -)"
    )
    assert made == []


@pytest.mark.parametrize(
    "name", ["dut", "dut.A", "dut.T.x", "dut.pos_1-b.z", "dut.ABCDEFGHIJKLMNOP", "dut.9.9"]
)
def test_dut_channel_names_of_the_design_are_taken(name):
    assert is_dut_channel(name)
    status = NiDaq("Dev1", task_factory=Factory()).configure(
        DaqConfig(FS, N, CONFIG.output, (INPUTS[0], InputChannel(name, "Dev1/ai1", 1.0)))
    )
    assert dict(status.skews_s) == pytest.approx({"reference": 0.0, name: 4e-6}, rel=1e-12)


def test_daq_config_needs_a_reference_and_a_dut_channel_by_the_design_s_names():
    out = CONFIG.output
    message = (
        "DAQ configuration: needs a 'reference' and at least one DUT input channel "
        "('dut', or 'dut.<position>')"
    )
    for inputs in (
        (INPUTS[0], INPUTS[5]),  # reference and drive only
        (INPUTS[1], INPUTS[2]),  # DUTs only
        (INPUTS[0], InputChannel("dut.A.x.y", "Dev1/ai1", 1.0)),  # no DUT name
    ):
        with pytest.raises(InputRefused) as info:
            DaqConfig(FS, N, out, inputs)
        assert str(info.value) == message
    with pytest.raises(InputRefused, match="names must be unique"):
        DaqConfig(FS, N, out, (INPUTS[0], INPUTS[1], INPUTS[1]))
    assert DaqConfig(FS, N, out, (INPUTS[0], INPUTS[4])).inputs[1].name == "dut.D-2"


def test_a_status_without_skews_keeps_an_empty_mapping_and_the_single_skew():
    status = DaqStatus(1000.0, 2e-6)
    assert dict(status.skews_s) == {} and status.skew_s == 2e-6
    assert DaqStatus(1000.0, 0.0).skews_s is not status.skews_s  # never a shared mapping


# --- TEDS per channel ---------------------------------------------------------------------


class FakeNi:
    """nidaqmx as far as TEDS goes: `script` maps a physical channel to the bytes its sensor
    holds or the error DAQmx raises; every call is appended to `events`."""

    def __init__(self, script: dict[str, bytes | Exception]) -> None:
        self.events: list[tuple[str, ...]] = []
        ni = self

        class PhysicalChannel:
            def __init__(self, name: str) -> None:
                self.name = name
                self.configured = False
                ni.events.append(("PhysicalChannel", name))

            def configure_teds(self, file_path=None):
                ni.events.append(("configure_teds", self.name, file_path))
                found = ni.script[self.name]
                if isinstance(found, Exception):
                    raise found
                self.configured = True

            @property
            def teds_bit_stream(self):
                ni.events.append(("teds_bit_stream", self.name))
                if not self.configured:  # DAQmx holds TEDS only once configured
                    raise daq_error(-200709, "TEDS sensor not detected")
                return np.frombuffer(ni.script[self.name], dtype=np.uint8)

        self.script = script
        self.system = SimpleNamespace(PhysicalChannel=PhysicalChannel)


def test_teds_is_read_per_channel_on_its_physical_input():
    voltage = bitstream_bytes(read_ted_file(DATA / "Voltage.ted"))
    accelerometer = bitstream_bytes(read_ted_file(DATA / "Accelerometer.ted"))
    ni = FakeNi(
        {
            "Dev1/ai0": accelerometer,
            "Dev1/ai4": voltage,
            "Dev1/ai2": daq_error(-200709, "TEDS sensor not detected"),
            "Dev1/ai6": daq_error(-200741, "TEDS not supported"),
            "Dev1/ai3": b"",
        }
    )
    teds = read_teds_channels(INPUTS, ni=SimpleNamespace(system=ni.system))
    assert list(teds) == ["reference", "dut.A", "dut.B", "dut.C", "dut.D-2"]  # not the drive
    assert teds["reference"] == ChannelTeds("Dev1/ai0", accelerometer)
    assert teds["dut.A"] == ChannelTeds("Dev1/ai4", voltage)
    assert decode(teds["dut.A"].bits()).basic.identity == "17/1/A1/12345"
    assert teds["reference"].decoded().template_id == 25
    assert teds["dut.B"] == ChannelTeds("Dev1/ai2", None, "no TEDS sensor detected")
    assert teds["dut.C"] == ChannelTeds("Dev1/ai6", None, "the channel does not support TEDS")
    assert teds["dut.D-2"] == ChannelTeds("Dev1/ai3", None, "no TEDS sensor detected")
    with pytest.raises(TedsError, match=r"^TEDS of Dev1/ai2: no TEDS sensor detected$"):
        teds["dut.B"].decoded()
    assert ni.events == [
        event
        for physical in ("Dev1/ai0", "Dev1/ai4", "Dev1/ai2", "Dev1/ai6", "Dev1/ai3")
        for event in (
            ("PhysicalChannel", physical),
            ("configure_teds", physical, None),  # no file: look for the sensor on the channel
            *([("teds_bit_stream", physical)] if physical not in ("Dev1/ai2", "Dev1/ai6") else []),
        )
    ]


def test_a_channel_s_other_daqmx_error_is_its_reason_and_the_others_are_read():
    voltage = bitstream_bytes(read_ted_file(DATA / "Voltage.ted"))
    ni = FakeNi(dict.fromkeys([c.physical for c in INPUTS], voltage))
    ni.script["Dev1/ai2"] = daq_error(-200220, "Device identifier is invalid")
    teds = read_teds_channels(INPUTS, ni=SimpleNamespace(system=ni.system))
    assert teds["dut.B"].data is None
    assert teds["dut.B"].reason.startswith("NI-DAQ Dev1/ai2 TEDS: device not found: ")
    assert "Device identifier is invalid" in teds["dut.B"].reason
    assert [name for name, t in teds.items() if t.data == voltage] == [
        "reference",
        "dut.A",
        "dut.C",
        "dut.D-2",
    ]


@pytest.mark.parametrize(
    ("error", "raised", "text"),
    [
        (daq_error(-88705, "Device has been removed"), DeviceLostError, "device lost"),
        (OSError("libnidaqmx.so: cannot open"), DaqNotFoundError, "NI-DAQmx is not installed"),
    ],
)
def test_a_lost_device_or_missing_driver_is_raised_not_given_as_a_channel_s_reason(
    error, raised, text
):
    ni = FakeNi(dict.fromkeys([c.physical for c in INPUTS], b"\x01"))
    ni.script["Dev1/ai4"] = error
    with pytest.raises(raised, match=text):
        read_teds_channels(INPUTS, ni=SimpleNamespace(system=ni.system))


def test_teds_read_refuses_a_physical_input_used_twice_before_reading_any():
    ni = FakeNi({})
    inputs = (*INPUTS, InputChannel("dut.E", "Dev1/ai6", 1.0))
    with pytest.raises(InputRefused) as info:
        read_teds_channels(inputs, ni=SimpleNamespace(system=ni.system))
    assert str(info.value) == (
        "NI-DAQ TEDS: input channels 'dut.C' and 'dut.E' are both on physical channel "
        "'Dev1/ai6'; each input needs its own"
    )
    assert ni.events == []


def test_channel_teds_holds_bytes_or_a_reason_never_both_or_neither():
    with pytest.raises(TedsError, match="either the bytes read or the reason"):
        ChannelTeds("Dev1/ai1", b"\x01", "no TEDS sensor detected")
    with pytest.raises(TedsError, match="either the bytes read or the reason"):
        ChannelTeds("Dev1/ai1", None)
    assert ChannelTeds("Dev1/ai1", b"\x05").bits() == (1, 0, 1, 0, 0, 0, 0, 0)


def test_reader_threads_are_gone_after_stop(factory):
    daq = NiDaq("Dev1", task_factory=factory)
    daq.configure(CONFIG)
    daq.start(np.zeros(N))
    daq.read_period(timeout_s=5.0)
    daq.stop()
    assert not [t for t in threading.enumerate() if t.name == "accelcal-nidaq-reader-Dev1"]
    with pytest.raises(HardwareError, match="before start"):
        daq.read_period(0.1)
