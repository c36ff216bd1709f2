"""NiDaq against mock DAQmx tasks: exact configuration, start order, reading, the zero-then-stop
sequence on every path, and error translation. No NI hardware or driver needed."""

from __future__ import annotations

import dataclasses
import math
import sys
import threading
from types import SimpleNamespace
from typing import ClassVar
from unittest import mock

import nidaqmx.errors
import nidaqmx.stream_readers
import numpy as np
import pytest
from nidaqmx.constants import (
    AcquisitionType,
    Coupling,
    ExcitationSource,
    RegenerationMode,
    TerminalConfiguration,
)

from hardware import nidaq
from hardware.errors import (
    DaqNotFoundError,
    DaqNotSupportedError,
    DaqTimeoutError,
    DeviceLostError,
    HardwareError,
)
from hardware.interfaces import Daq, DaqConfig, InputChannel, OutputChannel
from hardware.nidaq import NiDaq, translate_error

FS = 1000.0
ACTUAL_FS = 999.5
CONV_RATE = 250_000.0
N = 50

CONFIG = DaqConfig(
    sample_rate_hz=FS,
    period_samples=N,
    output=OutputChannel("Dev1/ao0", 5.0),
    inputs=(
        InputChannel("reference", "Dev1/ai0", 10.0, terminal="differential"),
        InputChannel("drive", "Dev1/ai3", 2.0, terminal="rse"),
        InputChannel(
            "dut",
            "Dev1/ai1",
            1.0,
            coupling="ac",
            iepe_current_a=0.004,
            terminal="pseudodifferential",
        ),
    ),
)


def daq_error(code: int, message: str = "scripted DAQmx error") -> nidaqmx.errors.DaqError:
    return nidaqmx.errors.DaqError(message, code)


class Rig:
    """A task factory whose mock tasks all hang off one manager mock, so `manager.mock_calls`
    is the global order of every call; `sleep` is recorded there too."""

    def __init__(self) -> None:
        self.manager = mock.MagicMock()
        self.tasks: list[mock.MagicMock] = []
        self.channels: list[SimpleNamespace] = []
        self.manager.sleep.return_value = None

    def __call__(self) -> mock.MagicMock:
        name = f"task{len(self.tasks)}"
        task = getattr(self.manager, name)
        task.timing.samp_clk_rate = ACTUAL_FS
        task.timing.ai_conv_rate = CONV_RATE

        def add_chan(physical, **kwargs):
            chan = SimpleNamespace(physical=physical, **kwargs)
            self.channels.append(chan)
            return chan

        task.ai_channels.add_ai_voltage_chan.side_effect = add_chan
        self.tasks.append(task)
        return task

    @property
    def ai(self) -> mock.MagicMock:
        return self.tasks[0]

    @property
    def ao(self) -> mock.MagicMock:
        return self.tasks[1]

    def order(self) -> list[str]:
        return [c[0] for c in self.manager.mock_calls]


class FakeReader:
    """AnalogMultiChannelReader stand-in: period k of channel i is i*10 + k + t/1000;
    `script[k]` (an exception) is raised on read k instead."""

    instances: ClassVar[list[FakeReader]] = []
    script: ClassVar[dict[int, BaseException]] = {}
    block: threading.Event | None = None  # when set: reads wait for this event

    def __init__(self, in_stream):
        self.in_stream = in_stream
        self.calls: list[dict] = []
        FakeReader.instances.append(self)

    def read_many_sample(self, data, number_of_samples_per_channel=-1, timeout=10.0):
        k = len(self.calls)
        self.calls.append({"n": number_of_samples_per_channel, "timeout": timeout, "id": id(data)})
        if FakeReader.block is not None:
            FakeReader.block.wait(2.0)
            raise daq_error(-88709, "task stopped under the read")
        if k in FakeReader.script:
            raise FakeReader.script[k]
        assert data.shape == (len(CONFIG.inputs), number_of_samples_per_channel)
        assert data.dtype == np.float64
        data[:] = np.arange(data.shape[0])[:, None] * 10.0 + k + np.arange(data.shape[1]) / 1000
        return number_of_samples_per_channel


@pytest.fixture
def rig(monkeypatch):
    FakeReader.instances = []
    FakeReader.script = {}
    FakeReader.block = None
    monkeypatch.setattr(nidaqmx.stream_readers, "AnalogMultiChannelReader", FakeReader)
    r = Rig()
    monkeypatch.setattr(nidaq, "_sleep", r.manager.sleep)
    return r


@pytest.fixture
def daq(rig):
    d = NiDaq("Dev1", task_factory=rig)
    yield d
    d.stop()


def expected_period(k: int) -> np.ndarray:
    return np.arange(3)[:, None] * 10.0 + k + np.arange(N) / 1000


def sine(amplitude: float = 1.0) -> np.ndarray:
    return amplitude * np.sin(2 * np.pi * np.arange(N) / N + 0.3)


def test_is_a_daq(daq):
    assert isinstance(daq, Daq)


def test_configure_exact_calls(rig, daq):
    status = daq.configure(CONFIG)

    assert len(rig.tasks) == 2
    ai, ao = rig.ai, rig.ao
    assert ai.ai_channels.add_ai_voltage_chan.call_args_list == [
        mock.call(
            "Dev1/ai0", min_val=-10.0, max_val=10.0, terminal_config=TerminalConfiguration.DIFF
        ),
        mock.call("Dev1/ai3", min_val=-2.0, max_val=2.0, terminal_config=TerminalConfiguration.RSE),
        mock.call(
            "Dev1/ai1",
            min_val=-1.0,
            max_val=1.0,
            terminal_config=TerminalConfiguration.PSEUDO_DIFF,
        ),
    ]
    ref, drive, dut = rig.channels
    assert dut.ai_coupling == Coupling.AC
    assert dut.ai_excit_src == ExcitationSource.INTERNAL
    assert dut.ai_excit_val == pytest.approx(0.004)
    for chan in (ref, drive):  # dc, no IEPE: left alone
        assert not hasattr(chan, "ai_coupling")
        assert not hasattr(chan, "ai_excit_src")
        assert not hasattr(chan, "ai_excit_val")
    ai.ao_channels.add_ao_voltage_chan.assert_not_called()
    ao.ai_channels.add_ai_voltage_chan.assert_not_called()
    ao.ao_channels.add_ao_voltage_chan.assert_called_once_with(
        "Dev1/ao0", min_val=-5.0, max_val=5.0
    )

    ai.timing.cfg_samp_clk_timing.assert_called_once_with(
        FS, sample_mode=AcquisitionType.CONTINUOUS, samps_per_chan=4 * N
    )
    ao.timing.cfg_samp_clk_timing.assert_called_once_with(
        ACTUAL_FS,
        source="/Dev1/ai/SampleClock",
        sample_mode=AcquisitionType.CONTINUOUS,
        samps_per_chan=N,
    )
    ao.triggers.start_trigger.cfg_dig_edge_start_trig.assert_called_once_with(
        "/Dev1/ai/StartTrigger"
    )
    assert ao.out_stream.regen_mode == RegenerationMode.ALLOW_REGENERATION

    assert status.actual_sample_rate_hz == ACTUAL_FS
    # inputs are (reference, drive, dut): the dut is converted two channels after the reference
    assert status.skew_s == pytest.approx(2 / CONV_RATE)
    ai.start.assert_not_called()
    ao.start.assert_not_called()


def test_skew_is_negative_when_dut_comes_first_and_zero_without_convert_clock(rig):
    config = DaqConfig(FS, N, CONFIG.output, (CONFIG.inputs[2], CONFIG.inputs[0]))
    assert NiDaq("Dev1", task_factory=rig).configure(config).skew_s == pytest.approx(-1 / CONV_RATE)

    def simultaneous():
        task = rig()
        type(task.timing).ai_conv_rate = mock.PropertyMock(side_effect=daq_error(-200452))
        return task

    assert NiDaq("Dev1", task_factory=simultaneous).configure(config).skew_s == 0.0


def test_start_arms_ao_before_ai_and_reads_periods_in_channel_order(rig, daq):
    daq.configure(CONFIG)
    period = sine()
    daq.start(period)

    order = rig.order()
    write, ao_start, ai_start = (
        order.index("task1.write"),
        order.index("task1.start"),
        order.index("task0.start"),
    )
    assert write < ao_start < ai_start
    args, kwargs = rig.ao.write.call_args
    np.testing.assert_array_equal(args[0], period)
    assert kwargs["auto_start"] is False
    assert FakeReader.instances[0].in_stream is rig.ai.in_stream
    assert daq.output_v == pytest.approx(period[-1])

    first = daq.read_period(timeout_s=2.0)
    second = daq.read_period(timeout_s=2.0)
    assert first.shape == (3, N)
    np.testing.assert_array_equal(first, expected_period(0))
    np.testing.assert_array_equal(second, expected_period(1))
    calls = FakeReader.instances[0].calls
    assert calls[0]["n"] == N
    assert calls[0]["id"] != calls[1]["id"]  # a pool of preallocated buffers


def test_read_period_returns_copies(rig, daq):
    daq.configure(CONFIG)
    daq.start(sine())
    blocks = [daq.read_period(timeout_s=2.0) for _ in range(10)]  # more than the pool holds
    for k, block in enumerate(blocks):
        np.testing.assert_array_equal(block, expected_period(k))


def assert_zero_then_stop(rig: Rig, start_index: int = 0) -> None:
    order = rig.order()[start_index:]
    ao_writes = [c for c in rig.ao.write.call_args_list]
    last = ao_writes[-1]
    np.testing.assert_array_equal(last.args[0], np.zeros(N))
    zero_write = max(i for i, name in enumerate(order) if name == "task1.write")
    assert zero_write < order.index("sleep") < order.index("task1.stop")
    assert rig.manager.sleep.call_args.args[0] >= N / ACTUAL_FS
    for task in ("task0", "task1"):
        assert order.index(f"{task}.stop") < order.index(f"{task}.close")
    rig.ai.close.assert_called_once()
    rig.ao.close.assert_called_once()


def test_stop_plays_zeros_then_stops_and_closes(rig, daq):
    daq.configure(CONFIG)
    daq.start(sine())
    daq.read_period(timeout_s=2.0)
    daq.stop()

    assert_zero_then_stop(rig)
    assert daq.output_v == 0.0
    calls = len(rig.manager.mock_calls)
    daq.stop()  # twice: nothing more happens
    daq.close()
    assert len(rig.manager.mock_calls) == calls
    with pytest.raises(HardwareError, match="before start"):
        daq.read_period(0.1)


def test_device_lost_mid_run_then_stop_still_zeroes_and_closes(rig, daq):
    FakeReader.script = {1: daq_error(-88705, "Device has been removed")}
    daq.configure(CONFIG)
    daq.start(sine(2.0))
    np.testing.assert_array_equal(daq.read_period(timeout_s=2.0), expected_period(0))
    with pytest.raises(DeviceLostError, match="Device has been removed"):
        daq.read_period(timeout_s=2.0)
    with pytest.raises(DeviceLostError):  # stays failed, no hang
        daq.read_period(timeout_s=2.0)
    # the broken tasks refuse to stop and close: stop() must not raise a second error
    rig.ao.stop.side_effect = daq_error(-88705, "Device has been removed")
    rig.ai.stop.side_effect = daq_error(-88705, "Device has been removed")
    rig.ai.close.side_effect = daq_error(-88705, "Device has been removed")

    daq.stop()

    assert_zero_then_stop(rig)
    assert daq.output_v == 0.0


def test_zero_write_fails_falls_back_to_on_demand_zero(rig, daq):
    daq.configure(CONFIG)
    daq.start(sine())
    rig.ao.write.side_effect = daq_error(-200010, "write failed")
    daq.stop()

    rig.manager.sleep.assert_not_called()
    rig.ao.stop.assert_called_once()
    rig.ao.close.assert_called_once()
    rig.ai.close.assert_called_once()
    fallback = rig.tasks[2]
    fallback.ao_channels.add_ao_voltage_chan.assert_called_once_with(
        "Dev1/ao0", min_val=-5.0, max_val=5.0
    )
    fallback.write.assert_called_once_with(0.0, auto_start=True)
    fallback.close.assert_called_once()
    assert daq.output_v == 0.0


def test_output_unknown_when_no_zero_can_be_written(rig):
    def factory():
        if len(rig.tasks) >= 2:
            raise daq_error(-88705, "Device has been removed")
        return rig()

    daq = NiDaq("Dev1", task_factory=factory)
    daq.configure(CONFIG)
    daq.start(sine())
    rig.ao.write.side_effect = daq_error(-88705, "Device has been removed")
    daq.stop()
    assert daq.output_v is None
    rig.ao.close.assert_called_once()


@pytest.mark.parametrize(
    ("code", "error"),
    [(-200284, DaqTimeoutError), (-88709, DeviceLostError), (-201003, DeviceLostError)],
)
def test_reader_errors_are_translated(rig, daq, code, error):
    FakeReader.script = {0: daq_error(code, f"DAQmx says {code}")}
    daq.configure(CONFIG)
    daq.start(sine())
    with pytest.raises(error, match=f"DAQmx says {code}"):
        daq.read_period(timeout_s=2.0)
    daq.stop()
    assert_zero_then_stop(rig)


def test_read_period_times_out_when_no_period_arrives(rig, daq):
    FakeReader.block = threading.Event()
    daq.configure(CONFIG)
    daq.start(sine())
    rig.ai.stop.side_effect = lambda: FakeReader.block.set()
    with pytest.raises(DaqTimeoutError, match=r"within 0\.05 s"):
        daq.read_period(timeout_s=0.05)
    daq.stop()  # unblocks the reader: its error is not reported
    assert_zero_then_stop(rig)


def test_start_failure_cleans_up_without_writing_zeros(rig, daq):
    daq.configure(CONFIG)
    rig.ai.start.side_effect = daq_error(-200088, "Task specified is invalid")
    with pytest.raises(HardwareError, match="Task specified is invalid") as info:
        daq.start(sine())
    assert type(info.value) is HardwareError
    assert len(rig.ao.write.call_args_list) == 1  # only the period; it never played
    rig.ao.stop.assert_called_once()
    rig.ao.close.assert_called_once()
    rig.ai.close.assert_called_once()
    assert daq.output_v == 0.0


def test_write_period_validates_and_writes(rig, daq):
    daq.configure(CONFIG)
    with pytest.raises(HardwareError, match="before start"):
        daq.write_period(sine())
    daq.start(sine())
    with pytest.raises(ValueError, match="50 samples"):
        daq.write_period(np.zeros(N + 1))
    bad = sine()
    bad[3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        daq.write_period(bad)
    with pytest.raises(ValueError, match="exceeds the AO range"):
        daq.write_period(sine(5.5))
    assert rig.ao.write.call_count == 1
    new = sine(4.0)
    daq.write_period(new)
    np.testing.assert_array_equal(rig.ao.write.call_args.args[0], new)
    assert daq.output_v == pytest.approx(new[-1])


def test_restart_after_stop_creates_new_tasks(rig, daq):
    daq.configure(CONFIG)
    daq.start(sine())
    daq.stop()
    daq.start(sine())
    assert len(rig.tasks) == 4
    rig.tasks[3].start.assert_called_once()
    np.testing.assert_array_equal(daq.read_period(timeout_s=2.0), expected_period(0))


@pytest.mark.parametrize(
    ("code", "error"),
    [
        (-200474, DaqTimeoutError),
        (-50405, DeviceLostError),
        (-200220, DaqNotFoundError),
        (-200077, DaqNotSupportedError),
        (-200010, HardwareError),
    ],
)
def test_translate_error(code, error):
    translated = translate_error(daq_error(code, "the DAQmx message"), "NI-DAQ Dev1")
    assert type(translated) is error
    assert "the DAQmx message" in str(translated)
    assert str(translated).startswith("NI-DAQ Dev1")


def test_configure_error_closes_tasks_and_names_devices(rig):
    def factory():
        task = rig()
        task.ai_channels.add_ai_voltage_chan.side_effect = daq_error(-200220, "Device identifier")
        return task

    system = SimpleNamespace(devices=[SimpleNamespace(name="Dev2")])
    with pytest.raises(DaqNotFoundError, match="devices present: Dev2"):
        NiDaq("Dev1", task_factory=factory, system=system).configure(CONFIG)
    for task in rig.tasks:
        task.close.assert_called_once()


def test_driver_missing_from_factory(rig):
    def factory():
        raise nidaqmx.errors.DaqNotFoundError("Could not find an installation of NI-DAQmx.")

    with pytest.raises(DaqNotFoundError) as info:
        NiDaq("Dev1", task_factory=factory).configure(CONFIG)
    assert str(info.value).startswith("NI-DAQmx is not installed: ")
    assert "ni.com" in str(info.value)


def test_driver_missing_from_os(rig):
    def factory():
        raise OSError("libnidaqmx.so: cannot open shared object file")

    with pytest.raises(DaqNotFoundError, match=r"^NI-DAQmx is not installed: .*libnidaqmx"):
        NiDaq("Dev1", task_factory=factory).configure(CONFIG)


def test_package_missing(monkeypatch):
    for name in [m for m in sys.modules if m == "nidaqmx" or m.startswith("nidaqmx.")]:
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(DaqNotFoundError, match=r"^NI-DAQmx is not installed: .*pip install"):
        NiDaq("Dev1").configure(CONFIG)


def test_default_factory_on_this_machine_without_driver():
    try:
        nidaqmx.system.System.local().driver_version  # noqa: B018
    except nidaqmx.errors.DaqNotFoundError:
        pass
    else:
        pytest.skip("NI-DAQmx driver installed here")
    daq = NiDaq("Dev1")
    with pytest.raises(DaqNotFoundError, match=r"^NI-DAQmx is not installed: "):
        daq.configure(CONFIG)
    daq.stop()
    assert daq.output_v == 0.0


# --- the zero write before stop, on every way out, with a plain fake task (docs/mutation.md) --
#
# Hand-computed for N = 50 samples at the actual rate 999.5 S/s: one period lasts
# 50 / 999.5 = 0.0500250125 s; stop() waits that plus FIFO_ALLOWANCE_S = 0.25 s, i.e.
# 0.3000250125 s; every AO write may take 2 * 0.0500250125 + 5 = 5.100050025 s.

PERIOD_S = 0.0500250125
ZERO_WAIT_S = 0.3000250125
WRITE_TIMEOUT_S = 5.100050025


class FakeTask:
    """A nidaqmx.Task stand-in that appends every call to a shared event list."""

    def __init__(self, name: str, events: list, fail: dict) -> None:
        self.name, self.events, self.fail = name, events, fail
        self.timing = SimpleNamespace(samp_clk_rate=ACTUAL_FS, ai_conv_rate=CONV_RATE)
        self.timing.cfg_samp_clk_timing = lambda *a, **k: None
        self.ai_channels = SimpleNamespace(add_ai_voltage_chan=lambda *a, **k: SimpleNamespace())
        self.ao_channels = SimpleNamespace(add_ao_voltage_chan=self._add_ao)
        start_trigger = SimpleNamespace(cfg_dig_edge_start_trig=lambda *a: None)
        self.triggers = SimpleNamespace(start_trigger=start_trigger)
        self.out_stream = SimpleNamespace()
        self.in_stream = SimpleNamespace()

    def _event(self, what: str, *args) -> None:
        self.events.append((f"{self.name}.{what}", *args))
        error = self.fail.get(f"{self.name}.{what}")
        if error is not None:
            if isinstance(error, list):  # fail only the first call(s)
                if error:
                    raise error.pop(0)
                return
            raise error

    def _add_ao(self, physical, min_val, max_val):
        self._event("add_ao", physical, min_val, max_val)

    def write(self, data, auto_start, timeout=None):
        if np.isscalar(data):  # the one-sample on-demand write
            value = "0 V" if data == 0.0 else f"{data} V"
        else:
            assert data.shape == (N,)
            value = "period" if np.any(data) else "zeros"
        self._event("write", value, auto_start, timeout)

    def start(self):
        self._event("start")

    def stop(self):
        self._event("stop")

    def close(self):
        self._event("close")


class FakeFactory:
    """Tasks named ai, ao, then fallback1, fallback2, ...; `fail` maps "task.call" to an error
    (raised on every call) or to a list of errors (raised once each, then the call succeeds)."""

    def __init__(self) -> None:
        self.events: list[tuple] = []
        self.fail: dict = {}
        self.made = 0

    def __call__(self) -> FakeTask:
        name = ("ai", "ao")[self.made] if self.made < 2 else f"task{self.made}"
        self.made += 1
        if self.fail.get("factory") and self.made > 2:
            raise self.fail["factory"]
        return FakeTask(name, self.events, self.fail)

    def names(self, start: int = 0) -> list[str]:
        return [e[0] for e in self.events[start:]]


ZERO_THEN_RELEASE = [
    ("ao.write", "zeros", False, pytest.approx(WRITE_TIMEOUT_S, rel=1e-9)),
    ("sleep", pytest.approx(ZERO_WAIT_S, rel=1e-9)),
    ("ao.stop",),
    ("ai.stop",),
    ("ao.close",),
    ("ai.close",),
]


@pytest.fixture
def fake(monkeypatch):
    FakeReader.instances = []
    FakeReader.script = {}
    FakeReader.block = None
    monkeypatch.setattr(nidaqmx.stream_readers, "AnalogMultiChannelReader", FakeReader)
    factory = FakeFactory()
    monkeypatch.setattr(nidaq, "_sleep", lambda s: factory.events.append(("sleep", s)))
    return factory


def started(fake: FakeFactory) -> tuple[NiDaq, int]:
    daq = NiDaq("Dev1", task_factory=fake)
    daq.configure(CONFIG)
    daq.start(sine())
    assert fake.events[-3:] == [
        ("ao.write", "period", False, pytest.approx(WRITE_TIMEOUT_S, rel=1e-9)),
        ("ao.start",),
        ("ai.start",),
    ]
    return daq, len(fake.events)


def test_hand_computed_period_and_waits():
    assert N / ACTUAL_FS == pytest.approx(PERIOD_S, rel=1e-9)
    assert nidaq.FIFO_ALLOWANCE_S == 0.25


@pytest.mark.parametrize("path", ["stop", "close", "reconfigure", "device lost", "stop fails"])
def test_every_way_out_writes_zeros_waits_then_stops_and_closes(fake, path):
    if path == "device lost":  # the second read fails like an unplugged device
        FakeReader.script = {1: daq_error(-88705, "Device has been removed")}
    daq, mark = started(fake)
    if path == "stop":
        daq.stop()
    elif path == "close":
        daq.close()
    elif path == "reconfigure":
        daq.configure(CONFIG)
    elif path == "device lost":
        daq.read_period(timeout_s=2.0)
        with pytest.raises(DeviceLostError):
            daq.read_period(timeout_s=2.0)
        fake.fail["ao.stop"] = daq_error(-88705, "Device has been removed")
        fake.fail["ai.close"] = daq_error(-88705, "Device has been removed")
        daq.stop()
    else:
        fake.fail["ao.stop"] = daq_error(-200010, "stop failed")
        fake.fail["ai.stop"] = daq_error(-200010, "stop failed")
        fake.fail["ao.close"] = daq_error(-200010, "close failed")
        daq.stop()
    # only the zero write and the release happen, in this order (reconfigure then builds
    # new tasks, which come after)
    assert fake.events[mark : mark + 6] == ZERO_THEN_RELEASE
    if path != "reconfigure":
        assert len(fake.events) == mark + 6
    assert daq.output_v == 0.0
    daq.stop()  # nothing more to do: no second zero write on a stopped device
    assert [e for e in fake.events[mark + 6 :] if e[0] == "ao.write"] == []


def test_failed_write_period_then_stop_still_writes_zeros(fake):
    daq, mark = started(fake)
    fake.fail["ao.write"] = [daq_error(-200010, "write failed")]  # once: the zeros go through
    with pytest.raises(HardwareError, match="write failed"):
        daq.write_period(sine(2.0))
    assert fake.events[mark][:2] == ("ao.write", "period")
    daq.stop()
    assert fake.events[mark + 1 :] == ZERO_THEN_RELEASE
    assert daq.output_v == 0.0


def test_zeros_refused_falls_back_to_an_on_demand_zero_after_release(fake):
    daq, mark = started(fake)
    fake.fail["ao.write"] = daq_error(-200010, "write failed")
    daq.stop()
    assert fake.events[mark:] == [
        ("ao.write", "zeros", False, pytest.approx(WRITE_TIMEOUT_S, rel=1e-9)),  # refused
        ("ao.stop",),  # no wait: nothing was queued
        ("ai.stop",),
        ("ao.close",),
        ("ai.close",),
        ("task2.add_ao", "Dev1/ao0", -5.0, 5.0),
        ("task2.write", "0 V", True, None),
        ("task2.close",),
    ]
    assert daq.output_v == 0.0


def test_on_demand_zero_refused_leaves_the_output_unknown_and_closes_its_task(fake):
    daq, mark = started(fake)
    fake.fail["ao.write"] = daq_error(-200010, "write failed")
    fake.fail["task2.write"] = daq_error(-88705, "Device has been removed")
    daq.stop()
    assert fake.names(mark)[-3:] == ["task2.add_ao", "task2.write", "task2.close"]
    assert daq.output_v is None
    # a later stop (the procedure stops again on its way out) must not report 0 V without
    # having written it: it tries the on-demand zero again
    fake.fail["task3.write"] = daq_error(-88705, "Device has been removed")
    mark = len(fake.events)
    daq.stop()
    assert fake.names(mark) == ["task3.add_ao", "task3.write", "task3.close"]
    assert daq.output_v is None
    daq.stop()  # and when that one works, the output is known to be 0 V
    assert fake.events[-3:] == [
        ("task4.add_ao", "Dev1/ao0", -5.0, 5.0),
        ("task4.write", "0 V", True, None),
        ("task4.close",),
    ]
    assert daq.output_v == 0.0


def test_on_demand_task_cannot_be_made_leaves_the_output_unknown(fake):
    daq, mark = started(fake)
    fake.fail["ao.write"] = daq_error(-200010, "write failed")
    fake.fail["factory"] = daq_error(-88705, "Device has been removed")
    daq.stop()
    assert fake.names(mark) == ["ao.write", "ao.stop", "ai.stop", "ao.close", "ai.close"]
    assert daq.output_v is None
    daq.stop()
    assert daq.output_v is None  # still unknown: nothing could be written


def test_stop_before_start_writes_nothing_and_releases(fake):
    daq = NiDaq("Dev1", task_factory=fake)
    daq.configure(CONFIG)
    mark = len(fake.events)
    daq.stop()
    assert fake.events[mark:] == [("ao.stop",), ("ai.stop",), ("ao.close",), ("ai.close",)]
    assert daq.output_v == 0.0


def test_failed_start_releases_without_zeros_and_refuses_writes(fake):
    daq = NiDaq("Dev1", task_factory=fake)
    daq.configure(CONFIG)
    mark = len(fake.events)
    fake.fail["ai.start"] = daq_error(-200088, "Task specified is invalid")
    with pytest.raises(HardwareError, match="Task specified is invalid"):
        daq.start(sine())
    assert fake.names(mark) == [
        "ao.write",
        "ao.start",
        "ai.start",  # refused: the AO task never got its trigger, nothing played
        "ao.stop",
        "ai.stop",
        "ao.close",
        "ai.close",
    ]
    assert daq.output_v == 0.0
    with pytest.raises(HardwareError, match="write_period before start"):
        daq.write_period(sine())


def test_write_period_after_a_reader_failure_raises_it_and_writes_nothing(fake):
    FakeReader.script = {0: daq_error(-88705, "Device has been removed")}
    daq, mark = started(fake)
    with pytest.raises(DeviceLostError):
        daq.read_period(timeout_s=2.0)
    with pytest.raises(DeviceLostError, match="Device has been removed"):
        daq.write_period(sine())
    assert fake.names(mark) == []
    daq.stop()
    assert fake.events[mark:] == ZERO_THEN_RELEASE


def test_write_period_sets_output_to_the_last_sample(fake):
    daq, mark = started(fake)
    new = sine(3.0)
    daq.write_period(new)
    assert fake.events[mark] == ("ao.write", "period", False, pytest.approx(WRITE_TIMEOUT_S))
    assert daq.output_v == pytest.approx(3.0 * math.sin(2 * math.pi * 49 / 50 + 0.3))
    daq.stop()
    assert daq.output_v == 0.0


def test_start_twice_is_refused_by_name_and_changes_nothing(fake):
    daq, mark = started(fake)
    with pytest.raises(HardwareError) as info:
        daq.start(sine())
    assert str(info.value) == "NI-DAQ Dev1: already running; stop() first"
    assert fake.events[mark:] == []
    with pytest.raises(HardwareError) as info:
        NiDaq("Dev1", task_factory=fake).write_period(sine())
    assert str(info.value) == "NI-DAQ Dev1: configure() first"
    daq.stop()
    with pytest.raises(HardwareError) as info:
        daq.write_period(sine())
    assert str(info.value) == "NI-DAQ Dev1: write_period before start()"


def test_reader_is_a_named_daemon_thread_joined_by_stop(fake):
    daq, _ = started(fake)
    readers = [t for t in threading.enumerate() if t.name == "accelcal-nidaq-reader-Dev1"]
    assert len(readers) == 1
    assert readers[0].daemon  # never keeps the interpreter alive if a run dies without stop()
    daq.stop()
    assert not readers[0].is_alive()


def test_every_failure_on_the_way_out_is_logged_word_for_word(fake, caplog):
    daq, _ = started(fake)
    for call in ("ao.write", "ao.stop", "ai.stop", "ao.close", "ai.close", "task2.write"):
        fake.fail[call] = RuntimeError("boom")
    fake.fail["task2.close"] = RuntimeError("gone")
    with caplog.at_level("WARNING", logger="hardware.nidaq"):
        daq.stop()
    assert [r.getMessage() for r in caplog.records] == [
        "NI-DAQ Dev1: could not write the zero period: boom",
        "NI-DAQ Dev1: stopping the AO task: boom",
        "NI-DAQ Dev1: stopping the AI task: boom",
        "NI-DAQ Dev1: closing the AO task: boom",
        "NI-DAQ Dev1: closing the AI task: boom",
        "NI-DAQ Dev1: could not set the output to 0 V: boom",
        "NI-DAQ Dev1: closing the 0 V task: gone",
    ]
    assert daq.output_v is None


def test_no_task_for_the_on_demand_zero_is_logged(fake, caplog):
    daq, _ = started(fake)
    fake.fail["ao.write"] = RuntimeError("boom")
    fake.fail["factory"] = RuntimeError("no task")
    with caplog.at_level("WARNING", logger="hardware.nidaq"):
        daq.stop()
    assert [r.getMessage() for r in caplog.records] == [
        "NI-DAQ Dev1: could not write the zero period: boom",
        "NI-DAQ Dev1: could not set the output to 0 V: NI-DAQ Dev1: no task",
    ]


def test_a_range_chosen_per_line_reaches_the_channels_min_and_max_at_every_configure(rig, daq):
    """Issue 32: stepped sine configures the DAQ per line with that line's ranges; each
    configure creates the AI channels with the chosen +-range as min_val/max_val."""
    daq.configure(CONFIG)
    narrow = DaqConfig(
        FS,
        N,
        CONFIG.output,
        tuple(dataclasses.replace(c, range_v=0.1) if c.name == "dut" else c for c in CONFIG.inputs),
    )
    daq.stop()
    daq.configure(narrow)
    ai = rig.tasks[2]  # a new AI task for the new configuration
    dut_call = ai.ai_channels.add_ai_voltage_chan.call_args_list[2]
    assert dut_call.args == ("Dev1/ai1",)
    assert dut_call.kwargs["min_val"] == -0.1 and dut_call.kwargs["max_val"] == 0.1
    ref_call = ai.ai_channels.add_ai_voltage_chan.call_args_list[0]
    assert ref_call.kwargs["max_val"] == 10.0  # the others as configured


def test_the_devices_bipolar_input_ranges_are_read_from_daqmx():
    device = SimpleNamespace(ai_voltage_rngs=[-0.1, 0.1, -10.0, 10.0, 0.0, 5.0, -1.0, 1.0])
    system = SimpleNamespace(devices={"Dev1": device})
    assert NiDaq("Dev1", system=system).input_ranges_v() == (0.1, 1.0, 10.0)  # 0-5 V: unipolar
    lost = SimpleNamespace(devices={})
    with pytest.raises(HardwareError, match="NI-DAQ Dev1"):
        NiDaq("Dev1", system=lost).input_ranges_v()
    none = SimpleNamespace(devices={"Dev1": SimpleNamespace(ai_voltage_rngs=[0.0, 5.0])})
    with pytest.raises(DaqNotSupportedError, match="no bipolar AI range"):
        NiDaq("Dev1", system=none).input_ranges_v()
