"""The `hardware.interfaces.Daq` protocol on a National Instruments DAQ through `nidaqmx`.

One AI task and one AO task (the drive). The AI task holds one voltage channel per
`DaqConfig.inputs` entry, in that order: the reference, every DUT channel ("dut", or
"dut.<position>[.<axis>]" in a several-DUT run) and the drive read-back, each with its own
range, terminal, coupling and IEPE current, all on the one AI sample clock; a name that is no
such channel, or two inputs on one physical channel, is refused before any device is touched.
On a multiplexed board the convert clock samples the channels one after another in that order,
1 / `ai_conv_rate` apart: `DaqStatus.skews_s` holds every input's delay after the reference
(0 on simultaneous-sampling boards), `skew_s` the first DUT channel's.

Synchronisation follows NI's shared-clock pattern: the AO task is clocked by the AI sample clock
(`/<device>/ai/SampleClock`) and armed on the AI start trigger (`/<device>/ai/StartTrigger`), so
it is started first and begins with the first AI sample.

The AO buffer is one period, regenerated. `write_period` writes a whole new period into that
buffer: with regeneration DAQmx accepts the write once the previous period has been
transferred, at the write position that follows it, so the new period starts on a period
boundary, after a latency of up to about one period plus the device's on-board FIFO.

A reader thread reads whole periods with `AnalogMultiChannelReader.read_many_sample` into a
small pool of preallocated (channels, N) float64 arrays and hands them over on a bounded queue;
`read_period` returns a copy, (channels, N) in `DaqConfig.inputs` order (DAQmx de-interleaves
the scans: GROUP_BY_CHANNEL). The pool holds two more arrays than the queue, so the reader never
overwrites an array that is queued or being copied; when nobody reads, the reader waits and the
DAQmx input buffer (four periods) overflows, which surfaces as an error from `read_period`.
Reader errors are passed on through the queue and re-raised (translated) by `read_period`.

`stop` writes a period of zeros, waits for it to play out, then stops and closes both tasks;
it does this on every path (also after an error) and never raises. If the zeros cannot be
written it falls back to a one-sample on-demand AO write of 0 V; if that fails too, `output_v`
becomes None (unknown), and stays so until a later `stop` manages the 0 V write.

`read_teds_channels` reads the TEDS of every sensor input on its own physical channel
(`PhysicalChannel.configure_teds()` then `teds_bit_stream`): per channel name the bytes, or the
reason there are none (`hardware.teds.ChannelTeds`).

nidaqmx is imported lazily; a missing Python package or NI-DAQmx driver raises
`DaqNotFoundError` whose message starts with "NI-DAQmx is not installed: ".
"""

from __future__ import annotations

import logging
import math
import queue
import threading
import time
from collections.abc import Callable, Sequence
from types import SimpleNamespace
from typing import Any

import numpy as np

from hardware.errors import (
    DaqNotFoundError,
    DaqNotSupportedError,
    DaqTimeoutError,
    DeviceLostError,
    HardwareError,
    InputRefused,
)
from hardware.interfaces import (
    DaqConfig,
    DaqStatus,
    InputChannel,
    checked_output_period,
    is_dut_channel,
)
from hardware.teds import ChannelTeds

log = logging.getLogger(__name__)

#: DAQmx error codes meaning "no data/answer in time".
TIMEOUT_CODES = frozenset({-200284, -200474, -200560, -50400})
#: DAQmx error codes meaning the device went away (unplugged, powered off, driver reset).
DEVICE_LOST_CODES = frozenset(
    {-88705, -88709, -88710, -50405, -50300, -201003, -200045, -200324, -89130, -201190}
)
#: The named device does not exist.
DEVICE_NOT_FOUND_CODES = frozenset({-200220})
#: The device cannot do what was asked (attribute value or attribute not supported).
NOT_SUPPORTED_CODES = frozenset({-200077, -200197})
#: DAQmx error codes meaning "no TEDS on this channel", with the reason given for them.
NO_TEDS = {-200709: "no TEDS sensor detected", -200741: "the channel does not support TEDS"}

#: How many finished periods may wait for `read_period`.
QUEUE_PERIODS = 4
#: AI buffer in periods.
AI_BUFFER_PERIODS = 4
#: Extra wait after the zero period was written, for the device's on-board AO FIFO (s).
FIFO_ALLOWANCE_S = 0.25

INSTALL_HINT = (
    "install the NI-DAQmx driver (runtime) from https://www.ni.com/en/support/downloads/"
    "drivers/download.ni-daq-mx.html (Windows or a supported Linux; "
    "`python -m nidaqmx installdriver` does it on Windows) and the Python package "
    '(`pip install nidaqmx`), or use the simulated stand (daq backend = "sim")'
)

_sleep = time.sleep  # tests replace this


def not_installed_message(detail: str = "") -> str:
    """The message for a missing nidaqmx package or NI-DAQmx driver."""
    text = f"NI-DAQmx is not installed: {INSTALL_HINT}"
    return f"{text} ({detail})" if detail else text


def import_nidaqmx() -> SimpleNamespace:
    """nidaqmx and the submodules used here, or DaqNotFoundError if the package is missing."""
    try:
        import nidaqmx
        import nidaqmx.constants
        import nidaqmx.errors
        import nidaqmx.stream_readers
        import nidaqmx.system
    except (ImportError, OSError) as exc:
        raise DaqNotFoundError(not_installed_message(f"{type(exc).__name__}: {exc}")) from None
    return SimpleNamespace(
        nidaqmx=nidaqmx,
        constants=nidaqmx.constants,
        errors=nidaqmx.errors,
        stream_readers=nidaqmx.stream_readers,
        system=nidaqmx.system,
    )


def translate_error(exc: BaseException, context: str = "NI-DAQ") -> HardwareError:
    """A nidaqmx (or OS) error as the stand's error type, with nidaqmx's message."""
    if isinstance(exc, HardwareError):
        return exc
    kind = type(exc).__name__
    module = type(exc).__module__ or ""
    if isinstance(exc, (ImportError, OSError)) or (
        module.startswith("nidaqmx") and kind in ("DaqNotFoundError", "DaqNotSupportedError")
    ):
        return DaqNotFoundError(not_installed_message(f"{kind}: {exc}"))
    code = getattr(exc, "error_code", None)
    message = str(exc).strip() or kind
    if code in TIMEOUT_CODES:
        return DaqTimeoutError(f"{context}: timed out: {message}")
    if code in DEVICE_LOST_CODES:
        return DeviceLostError(f"{context}: device lost: {message}")
    if code in DEVICE_NOT_FOUND_CODES:
        return DaqNotFoundError(f"{context}: device not found: {message}")
    if code in NOT_SUPPORTED_CODES:
        return DaqNotSupportedError(f"{context}: not supported by the device: {message}")
    return HardwareError(f"{context}: {message}")


_TERMINALS = {
    "default": "DEFAULT",
    "differential": "DIFF",
    "pseudodifferential": "PSEUDO_DIFF",
    "rse": "RSE",
    "nrse": "NRSE",
}


class NiDaq:
    """An NI DAQ device (e.g. "Dev1", "cDAQ1Mod1") behind the `Daq` protocol.

    `task_factory` makes a new DAQmx task (default `nidaqmx.Task`); `system` is a
    `nidaqmx.system.System` used only to list the devices present when the device name is
    unknown (default `System.local()`).
    """

    def __init__(
        self,
        device: str,
        *,
        task_factory: Callable[[], Any] | None = None,
        system: Any = None,
    ):
        if not device or "/" in device:
            raise InputRefused(f"NI-DAQ: device name must be like 'Dev1', got {device!r}")
        self.device = device
        self._task_factory = task_factory
        self._system = system
        self._context = f"NI-DAQ {device}"
        self._config: DaqConfig | None = None
        self._ai: Any = None
        self._ao: Any = None
        self._actual_rate: float | None = None
        self._running = False
        self._generating = False
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=QUEUE_PERIODS)
        self._stop_event = threading.Event()
        self._reader: threading.Thread | None = None
        self._failure: HardwareError | None = None
        self._output_v: float | None = 0.0
        self._lock = threading.RLock()

    # --- the Daq protocol -------------------------------------------------------------------

    def configure(self, config: DaqConfig) -> DaqStatus:
        """Create and configure the AI and AO tasks; return the actual rate and the skews
        (InputRefused naming the channel, before anything is touched, for a channel this
        driver cannot take)."""
        check_inputs(config.inputs, self._context)
        with self._lock:
            self.stop()
            self._config = config
            self._create_tasks()
            assert self._actual_rate is not None
            names = [c.name for c in config.inputs]
            conv_rate = self._conv_rate()  # 0: simultaneous sampling, no convert clock
            first = names.index("reference")
            skews = {n: (i - first) / conv_rate if conv_rate else 0.0 for i, n in enumerate(names)}
            dut = next(n for n in names if is_dut_channel(n))
            return DaqStatus(self._actual_rate, skew_s=skews[dut], skews_s=skews)

    def start(self, period_v: np.ndarray) -> None:
        """Write one period to AO, arm AO, start AI (which starts both) and the reader."""
        with self._lock:
            config = self._require_config()
            if self._running:
                raise HardwareError(f"{self._context}: already running; stop() first")
            data = self._checked(period_v)
            if self._ai is None or self._ao is None:
                self._create_tasks()
            nidaqmx = import_nidaqmx()
            n = config.period_samples
            self._queue = queue.Queue(maxsize=QUEUE_PERIODS)
            self._stop_event = threading.Event()
            self._failure = None
            self._running = True
            try:
                self._ao.write(data, auto_start=False, timeout=self._write_timeout_s())
                reader = nidaqmx.stream_readers.AnalogMultiChannelReader(self._ai.in_stream)
                self._ao.start()  # armed: waits for the AI start trigger and sample clock
                self._ai.start()
                self._generating = True
                self._output_v = float(data[-1])
                buffers = [
                    np.zeros((len(config.inputs), n), dtype=np.float64)
                    for _ in range(QUEUE_PERIODS + 2)
                ]
                self._reader = threading.Thread(
                    target=self._read_loop,
                    args=(reader, buffers, n, self._stop_event, self._queue),
                    name=f"accelcal-nidaq-reader-{self.device}",
                    daemon=True,
                )
                self._reader.start()
            except Exception as exc:
                error = translate_error(exc, self._context)
                self.stop()
                raise error from exc

    def write_period(self, period_v: np.ndarray) -> None:
        """Replace the output from the next period boundary on (latency up to about one
        period plus the AO FIFO; the write waits until the buffer has room)."""
        with self._lock:
            data = self._checked(period_v)
            if not self._running or self._ao is None:
                raise HardwareError(f"{self._context}: write_period before start()")
            if self._failure is not None:
                raise self._failure
            try:
                self._ao.write(data, auto_start=False, timeout=self._write_timeout_s())
            except Exception as exc:
                raise translate_error(exc, self._context) from exc
            self._output_v = float(data[-1])

    def read_period(self, timeout_s: float = 10.0) -> np.ndarray:
        """The next whole period, (channels, N) volts in `DaqConfig.inputs` order."""
        if self._failure is not None:
            raise self._failure
        if not self._running:
            raise HardwareError(f"{self._context}: read_period before start()")
        try:
            item = self._queue.get(timeout=timeout_s)
        except queue.Empty:
            raise DaqTimeoutError(
                f"{self._context}: no period of samples within {timeout_s:g} s"
            ) from None
        if isinstance(item, BaseException):
            self._failure = translate_error(item, self._context)
            raise self._failure from item
        return item.copy()

    def stop(self) -> None:
        """Play a period of 0 V, then stop and close both tasks. Never raises."""
        with self._lock:
            ao, ai, reader, config = self._ao, self._ai, self._reader, self._config
            zeroed = self._output_v is not None  # unknown stays unknown until 0 V is written
            if self._generating and ao is not None and config is not None:
                zeroed = self._play_zeros(ao, config)
            self._stop_event.set()
            for task, what in ((ao, "AO"), (ai, "AI")):
                if task is not None:
                    _quietly(task.stop, f"{self._context}: stopping the {what} task")
            if reader is not None and reader is not threading.current_thread():
                reader.join(timeout=5.0)
            for task, what in ((ao, "AO"), (ai, "AI")):
                if task is not None:
                    _quietly(task.close, f"{self._context}: closing the {what} task")
            if not zeroed and config is not None:
                zeroed = self._zero_on_demand(config)
            self._ao = self._ai = self._reader = None
            self._running = self._generating = False
            self._output_v = 0.0 if zeroed else None

    def close(self) -> None:
        self.stop()

    @property
    def output_v(self) -> float | None:
        """The last value written to the output (0.0 when stopped; None if unknown)."""
        return self._output_v

    def input_ranges_v(self) -> tuple[float, ...]:
        """The device's bipolar analog input ranges, +-V (DAQmx `ai_voltage_rngs`: pairs of
        low, high; a range is kept when it is symmetric about 0 V)."""
        try:
            system = self._system
            if system is None:
                system = import_nidaqmx().system.System.local()
            pairs = list(system.devices[self.device].ai_voltage_rngs)
        except Exception as exc:
            raise translate_error(exc, self._context) from None
        ranges = {
            float(high)
            for low, high in zip(pairs[0::2], pairs[1::2], strict=False)
            if high > 0 and math.isclose(-low, high, rel_tol=1e-6)
        }
        if not ranges:
            raise DaqNotSupportedError(f"{self._context}: the device lists no bipolar AI range")
        return tuple(sorted(ranges))

    # --- internals --------------------------------------------------------------------------

    def _new_task(self) -> Any:
        factory = self._task_factory
        try:
            if factory is None:
                factory = import_nidaqmx().nidaqmx.Task
            return factory()
        except Exception as exc:
            raise translate_error(exc, self._context) from None

    def _create_tasks(self) -> None:
        """Create, configure and verify both tasks (closes them again on any error)."""
        config = self._require_config()
        nidaqmx = import_nidaqmx()
        constants = nidaqmx.constants
        try:
            self._ai = self._new_task()
            self._ao = self._new_task()
            ai, ao = self._ai, self._ao
            for channel in config.inputs:
                terminal = getattr(constants.TerminalConfiguration, _TERMINALS[channel.terminal])
                chan = ai.ai_channels.add_ai_voltage_chan(
                    channel.physical,
                    min_val=-channel.range_v,
                    max_val=channel.range_v,
                    terminal_config=terminal,
                )
                if channel.coupling == "ac":
                    chan.ai_coupling = constants.Coupling.AC
                if channel.iepe_current_a > 0:
                    chan.ai_excit_src = constants.ExcitationSource.INTERNAL
                    chan.ai_excit_val = channel.iepe_current_a
            out = config.output
            ao.ao_channels.add_ao_voltage_chan(
                out.physical, min_val=-out.range_v, max_val=out.range_v
            )
            n = config.period_samples
            ai.timing.cfg_samp_clk_timing(
                config.sample_rate_hz,
                sample_mode=constants.AcquisitionType.CONTINUOUS,
                samps_per_chan=n * AI_BUFFER_PERIODS,
            )
            actual = float(ai.timing.samp_clk_rate)
            if not (math.isfinite(actual) and actual > 0):
                raise HardwareError(f"{self._context}: device reports sample rate {actual!r}")
            ao.timing.cfg_samp_clk_timing(
                actual,
                source=f"/{self.device}/ai/SampleClock",
                sample_mode=constants.AcquisitionType.CONTINUOUS,
                samps_per_chan=n,
            )
            ao.triggers.start_trigger.cfg_dig_edge_start_trig(f"/{self.device}/ai/StartTrigger")
            ao.out_stream.regen_mode = constants.RegenerationMode.ALLOW_REGENERATION
            self._actual_rate = actual
        except Exception as exc:
            error = translate_error(exc, self._context)
            if getattr(exc, "error_code", None) in DEVICE_NOT_FOUND_CODES:
                error = DaqNotFoundError(f"{error} ({self._devices_present()})")
            for task in (self._ao, self._ai):
                if task is not None:
                    _quietly(task.close, f"{self._context}: closing a task after an error")
            self._ai = self._ao = None
            raise error from exc

    def _conv_rate(self) -> float:
        """The AI convert rate in Hz; 0 on simultaneous-sampling boards (no convert clock)."""
        try:
            rate = float(self._ai.timing.ai_conv_rate)
        except Exception as exc:  # not supported on simultaneous-sampling devices
            log.debug("%s: no AI convert rate (%s); skew 0", self._context, exc)
            return 0.0
        return rate if math.isfinite(rate) and rate > 0 else 0.0

    def _devices_present(self) -> str:
        try:
            system = self._system
            if system is None:
                system = import_nidaqmx().system.System.local()
            names = [d.name for d in system.devices]
        except Exception as exc:
            return f"devices present could not be listed: {exc}"
        return "devices present: " + (", ".join(names) if names else "none")

    def _read_loop(
        self,
        reader: Any,
        buffers: list[np.ndarray],
        n: int,
        stop_event: threading.Event,
        out: queue.Queue[Any],
    ) -> None:
        timeout = self._period_s() + 10.0
        index = 0
        while not stop_event.is_set():
            buffer = buffers[index % len(buffers)]
            index += 1
            try:
                reader.read_many_sample(buffer, number_of_samples_per_channel=n, timeout=timeout)
                item: Any = buffer
            except Exception as exc:
                if stop_event.is_set():
                    return  # the tasks were stopped under the read
                item = exc
            while not stop_event.is_set():
                try:
                    out.put(item, timeout=0.1)
                    break
                except queue.Full:
                    continue
            if isinstance(item, BaseException):
                return

    def _play_zeros(self, ao: Any, config: DaqConfig) -> bool:
        """Write a zero period and wait until it plays. False if the write failed."""
        try:
            ao.write(
                np.zeros(config.period_samples), auto_start=False, timeout=self._write_timeout_s()
            )
        except Exception as exc:
            log.warning("%s: could not write the zero period: %s", self._context, exc)
            return False
        _sleep(self._period_s() + FIFO_ALLOWANCE_S)
        return True

    def _zero_on_demand(self, config: DaqConfig) -> bool:
        """Fallback: set the AO channel to 0 V with a one-sample on-demand task."""
        try:
            task = self._new_task()
        except Exception as exc:
            log.warning("%s: could not set the output to 0 V: %s", self._context, exc)
            return False
        try:
            out = config.output
            task.ao_channels.add_ao_voltage_chan(
                out.physical, min_val=-out.range_v, max_val=out.range_v
            )
            task.write(0.0, auto_start=True)
            return True
        except Exception as exc:
            log.warning("%s: could not set the output to 0 V: %s", self._context, exc)
            return False
        finally:
            _quietly(task.close, f"{self._context}: closing the 0 V task")

    def _period_s(self) -> float:
        config = self._require_config()
        return config.period_samples / (self._actual_rate or config.sample_rate_hz)

    def _write_timeout_s(self) -> float:
        return 2.0 * self._period_s() + 5.0

    def _require_config(self) -> DaqConfig:
        if self._config is None:
            raise HardwareError(f"{self._context}: configure() first")
        return self._config

    def _checked(self, period_v: np.ndarray) -> np.ndarray:
        return checked_output_period(period_v, self._require_config(), self._context)


def check_inputs(inputs: Sequence[InputChannel], context: str) -> None:
    """InputRefused naming the channel: a name other than "reference", "drive" or a DUT
    channel's, a physical channel string naming no or several inputs (a list or a range), or
    two inputs on one physical channel (DAQmx names are case-insensitive)."""
    seen: dict[str, str] = {}
    for channel in inputs:
        name, physical = channel.name, channel.physical
        if name not in ("reference", "drive") and not is_dut_channel(name):
            raise InputRefused(
                f"{context}: input channel {name!r}: not a channel name ('reference', 'drive', "
                "'dut', 'dut.<position>' or 'dut.<position>.<axis>'; a position or axis is 1-16 "
                "of A-Z a-z 0-9 _ -)"
            )
        key = physical.strip().lstrip("/").lower()
        if not key or "," in key or ":" in key:
            raise InputRefused(
                f"{context}: input channel {name!r}: physical channel {physical!r} must name "
                "one input, e.g. 'Dev1/ai1'"
            )
        if key in seen:
            raise InputRefused(
                f"{context}: input channels {seen[key]!r} and {name!r} are both on physical "
                f"channel {physical!r}; each input needs its own"
            )
        seen[key] = name


def _quietly(action: Callable[[], Any], what: str) -> None:
    """Run a clean-up action; log (never raise) its error: the task may already be broken."""
    try:
        action()
    except Exception as exc:
        log.warning("%s: %s", what, exc)


# --- TEDS (IEEE 1451.4) on a physical channel: read, and write only when asked --------------


def read_teds_bits(physical_channel: str, *, ni: SimpleNamespace | None = None) -> tuple[int, ...]:
    """The TEDS bits of a physical channel (e.g. "Dev1/ai1") as DAQmx reads them from the
    sensor (PhysicalChannel.teds_bit_stream, bytes LSB first); HardwareError when none."""
    from hardware.teds import bits_from_bytes

    ni = ni or import_nidaqmx()
    try:
        channel = ni.system.PhysicalChannel(physical_channel)
        channel.configure_teds()  # DAQmx scans the sensor mounted now (not the last one seen)
        data = bytes(channel.teds_bit_stream)
    except Exception as exc:
        raise translate_error(exc, f"NI-DAQ {physical_channel} TEDS") from None
    if not data:
        raise DaqNotFoundError(f"NI-DAQ {physical_channel}: no TEDS sensor found on the channel")
    return bits_from_bytes(data)


def write_teds_bits(
    physical_channel: str, bits: tuple[int, ...], *, ni: SimpleNamespace | None = None
) -> None:
    """Write TEDS bits to the sensor on a physical channel (its Basic TEDS left as it is)."""
    from hardware.teds import bitstream_bytes

    ni = ni or import_nidaqmx()
    try:
        channel = ni.system.PhysicalChannel(physical_channel)
        channel.write_to_teds_from_array(
            list(bitstream_bytes(bits)),
            basic_teds_options=ni.constants.WriteBasicTEDSOptions.DO_NOT_WRITE,
        )
    except Exception as exc:
        raise translate_error(exc, f"NI-DAQ {physical_channel} TEDS write") from None


def read_teds_channels(
    inputs: Sequence[InputChannel], *, ni: SimpleNamespace | None = None
) -> dict[str, ChannelTeds]:
    """The TEDS of every sensor input (all but "drive"), in `inputs` order: per channel name
    the bytes DAQmx reads from the sensor on its physical channel (`configure_teds()` with no
    file looks for a TEDS sensor there, then `teds_bit_stream`), or the reason there are none.
    InputRefused (`check_inputs`) before anything is read; DaqNotFoundError when NI-DAQmx is
    missing, DeviceLostError when the device goes away: no channel could be read."""
    check_inputs(inputs, "NI-DAQ TEDS")
    ni = ni or import_nidaqmx()
    out: dict[str, ChannelTeds] = {}
    for channel in inputs:
        if channel.name == "drive":
            continue
        physical = channel.physical
        try:
            phys = ni.system.PhysicalChannel(physical)
            phys.configure_teds()
            data = bytes(int(b) for b in phys.teds_bit_stream)
        except Exception as exc:
            error = translate_error(exc, f"NI-DAQ {physical} TEDS")
            lost = isinstance(error, DeviceLostError)
            if lost or str(error).startswith("NI-DAQmx is not installed: "):
                raise error from None
            none = NO_TEDS.get(getattr(exc, "error_code", None) or 0)
            out[channel.name] = ChannelTeds(physical, None, none or str(error))
        else:
            found = any(data)  # nothing, or an empty memory
            out[channel.name] = ChannelTeds(
                physical, data if found else None, "" if found else NO_TEDS[-200709]
            )
    return out
