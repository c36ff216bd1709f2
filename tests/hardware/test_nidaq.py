"""NiDaq against mock DAQmx tasks: exact configuration, start order, reading, the zero-then-stop
sequence on every path, and error translation. No NI hardware or driver needed."""

from __future__ import annotations

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
