"""The stand as the phases use it: the drive-limit gate, the output queue, fades and
crossfades, the power amplifier, one checked and recorded period at a time, settling.

Every output period passes `limited_drive`. A `Segment` says what is being played: the whole
multisine plan (lines by DFT) or one stepped-sine line (lines by three-parameter sine fit).
"""

from __future__ import annotations

import logging
import math
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from app.io.hdf5 import RecordingWriter
from app.procedure.errors import Aborted, DriveLimitError, ProcedureError
from app.procedure.events import Event, PeriodBlock, State
from app.procedure.preflight import OVERLOAD_FRACTION
from app.procedure.ranging import with_ranges
from app.procedure.settings import RunSettings
from app.stand.open import Stand
from dsp.multisine import Plan, fade_envelope, fade_out_envelope, fade_out_samples
from dsp.sinefit import sine_fit
from dsp.spectral import period_spectrum, settle_excess
from dsp.tones import LineLeak, line_leak
from hardware.errors import AmplifierFaultError, DeviceLostError, HardwareError, OverloadError
from hardware.interfaces import DaqConfig, is_dut_channel

log = logging.getLogger(__name__)

PAUSE_FRACTION = 0.1  # 0 V for more than this share of a period: a pause, not excitation


def limited_drive(period_v: np.ndarray, limit_v: float) -> np.ndarray:
    """The one gate every output period passes on its way to the DAQ (identification,
    equalisation, crossfades, stepped sine, fades, zeros): the period as float volts, or
    DriveLimitError when any |sample| exceeds `limit_v` (V) or is not finite."""
    x = np.asarray(period_v, dtype=float)
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    if not math.isfinite(peak) or peak > limit_v:
        raise DriveLimitError(
            f"drive peak {peak:.4g} V exceeds the stand's drive limit {limit_v:g} V "
            "(limits.drive_peak_v, daq.output.range_v): refused before it was played; lower "
            "the level or the identification drive"
        )
    return x


@dataclass(frozen=True)
class Segment:
    """What the output plays: a plan and how its line spectra are read from a period."""

    plan: Plan
    one_line: bool = False  # stepped sine: one line by sine fit, blocks shorter than the plan's

    def lines(self, pair: np.ndarray) -> np.ndarray:
        """Complex line amplitudes of (reference, DUT), shape (2, lines)."""
        if self.one_line:  # IEEE 1057 three-parameter fit of both channels
            return sine_fit(pair, self.plan.frequencies_hz[0], self.plan.sample_rate_hz)[:, None]
        return period_spectrum(pair)[:, self.plan.bins]


@dataclass(frozen=True)
class Settled:
    """Two consecutive periods that agree: the table acceleration per line (complex, m/s^2),
    the last period's line spectra (reference, DUT) and both periods as read."""

    acceleration: np.ndarray
    lines: tuple[np.ndarray, np.ndarray]
    blocks: tuple[np.ndarray, np.ndarray]


class InputRangeOverload(OverloadError):
    """A DAQ input reached the limit of the range it is configured with (not the measuring
    amplifier's overload): a run that picked that range may go back to a larger one."""


class StandIO:
    """Drive out, periods in, for one run; thread-safe `abort` and `emergency_stop`."""

    def __init__(
        self,
        stand: Stand,
        plan: Plan,
        settings: RunSettings,
        emit: Callable[[Event], None],
        log_line: Callable[[str], None],
        announce: Callable[[State], None],
    ):
        self.stand = stand
        self.settings = settings
        self.segment = Segment(plan)
        self.emit = emit
        self.log = log_line
        self.announce = announce  # a state change: logged and sent to the listener
        config = stand.config
        self.inputs = config.inputs
        self.channel_index: dict[str, int] = {c.name: i for i, c in enumerate(self.inputs)}
        # the DUT channel the run's own estimate reads: "dut", or with several DUTs (issue 36)
        # the first "dut.<position>"; the others are recorded to `member_writers`
        self.dut_name = "dut"
        if "dut" not in self.channel_index:
            self.dut_name = next((n for n in self.channel_index if is_dut_channel(n)), "dut")
        self.member_writers: dict[str, RecordingWriter] = {}
        self.ranges: dict[str, float] = self._named_ranges()
        self.drive_limit_v = min(config.limits.drive_peak_v, config.output.range_v)
        self.writer: RecordingWriter | None = None
        self.drive = np.zeros(plan.period_samples)  # the steady drive (what a fade-out fades)
        self.played = self.drive  # the period the output plays now
        self.queue: deque[np.ndarray] = deque()  # written, not played yet: each plays in turn
        self.periods_read = 0
        self.peak_played_v = 0.0  # the largest drive sample played so far (V)
        self._excited_before_s = 0.0  # the shaker's running time in bursts already ended
        self._burst: tuple[int, int] | None = None  # first, last non-zero sample of this burst
        self._segment_samples = 0  # samples played since the segment began
        self.recording_full = False  # the disk is full: no more periods are appended
        self.power_on = False  # the power amplifier's output was enabled by this run
        self.power_failed = False  # the power amplifier failed: no more polling
        self.emergency = False
        self.in_transition = False  # a fade or crossfade period is playing: let it finish
        self._abort_reason: str | None = None
        self._abort_lock = threading.Lock()

    # --- control (thread-safe) ------------------------------------------------------------

    def abort(self, reason: str) -> None:
        """Ask the run to fade out and stop at the next period boundary."""
        with self._abort_lock:
            if self._abort_reason is None:
                self._abort_reason = reason

    def emergency_stop(self) -> None:
        """Zero the drive at once (no fade), from any thread; the run then ends aborted."""
        with self._abort_lock:
            self.emergency = True
            self._abort_reason = "emergency stop"
        try:
            self.stand.daq.stop()
        except Exception:  # the run's own `finally` stops again
            pass

    # --- output -----------------------------------------------------------------------------

    def set_ranges(self, ranges: dict[str, float]) -> None:
        """The named input channels' +-ranges (V) from the next DAQ configuration on (the
        overload check follows them)."""
        if self.dut_name != "dut" and "dut" in ranges:  # several DUTs: the DUT range on each
            dut = ranges["dut"]  # DUT channel the ranges do not name (named ones: their own)
            spread = {n: dut for n in self.channel_index if is_dut_channel(n) and n not in ranges}
            ranges = {**ranges, **spread, self.dut_name: dut}
        self.inputs = with_ranges(self.inputs, ranges)
        self.ranges = self._named_ranges()

    def _named_ranges(self) -> dict[str, float]:
        """Each input's +-range (V) by name; with several DUTs "dut" too (the run's own DUT
        channel's, as the single-DUT phases ask for it)."""
        ranges = {c.name: c.range_v for c in self.inputs}
        if self.dut_name != "dut" and self.dut_name in ranges:
            ranges["dut"] = ranges[self.dut_name]
        return ranges

    def reconfigure(self, ranges: dict[str, float]) -> bool:
        """The input ranges changed between phases: fade out, stop, the DAQ configured anew
        with them at the segment's rate and period, the segment begun again from 0 V. False
        (nothing done) when the ranges are those in use."""
        if all(self.ranges.get(name) == value for name, value in ranges.items()):
            return False
        if np.any(self.drive != 0):
            # the check during the fade on the larger of the two (the DAQ clips at its own)
            self.set_ranges({n: max(v, self.ranges.get(n, v)) for n, v in ranges.items()})
            self.fade_out()
        self.stand.daq.stop()
        self.set_ranges(ranges)
        if self.writer is not None:
            self.writer.widen_ranges(self.ranges)
        for name, writer in self.member_writers.items():  # each other DUT: its own channel's
            writer.widen_ranges({**self.ranges, "dut": self.ranges[name]})
        plan = self.segment.plan
        self.stand.daq.configure(
            DaqConfig(
                plan.sample_rate_hz, plan.period_samples, self.stand.config.output, self.inputs
            )
        )
        self.begin(self.segment)
        self.log(
            "input ranges: "
            + ", ".join(f"{name} +-{value:g} V" for name, value in sorted(self.ranges.items()))
        )
        return True

    def split_channels(self, block: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(reference, DUT) samples of a period as read."""
        return block[self.channel_index["reference"]], block[self.channel_index[self.dut_name]]

    def pair(self, block: np.ndarray) -> np.ndarray:
        """Rows (reference, DUT) of a period as read."""
        return block[[self.channel_index["reference"], self.channel_index[self.dut_name]]]

    @property
    def excited_s(self) -> float:
        """How long the shaker has run (s): from the first to the last non-zero drive sample of
        each burst of drive (fades included; background and pauses, 0 V for more than
        PAUSE_FRACTION of a period, not)."""
        if self._burst is None:
            return self._excited_before_s
        first, last = self._burst
        return self._excited_before_s + (last - first + 1) / self.segment.plan.sample_rate_hz

    def _count_excitation(self, played: np.ndarray) -> None:
        """Bursts of drive: a burst ends at a pause, the drive at exactly 0 V for more than
        PAUSE_FRACTION of a period (a whole zero period, or within periods: a check burst at
        the start of one, the next burst's fade-in at the end of another; issue 34). A
        multisine is exactly 0 V at single samples only."""
        moving = np.flatnonzero(played)
        if not moving.size:
            self._end_burst()
            self._segment_samples += played.size
            return
        at = self._segment_samples + moving
        pause = max(1, int(PAUSE_FRACTION * played.size))
        breaks = np.flatnonzero(np.diff(at) > pause)
        starts = np.concatenate(([at[0]], at[breaks + 1]))
        ends = np.concatenate((at[breaks], [at[-1]]))
        for start, end in zip(starts, ends, strict=True):
            if self._burst and start - self._burst[1] > pause:
                self._end_burst()
            first = self._burst[0] if self._burst else int(start)
            self._burst = (first, int(end))
        self._segment_samples += played.size

    def _end_burst(self) -> None:
        self._excited_before_s = self.excited_s
        self._burst = None

    def begin(self, segment: Segment) -> None:
        """Play `segment` from 0 V: the output starts with a zero period."""
        self._end_burst()
        self._segment_samples = 0
        self.segment = segment
        self.drive = self.played = np.zeros(segment.plan.period_samples)
        self.queue.clear()
        self.start(self.drive)

    def write(self, drive: np.ndarray) -> None:
        """Queue one period of drive: it plays after those written before it (Daq protocol)."""
        self.stand.daq.write_period(limited_drive(drive, self.drive_limit_v))
        self.queue.append(drive)

    def start(self, drive: np.ndarray) -> None:
        """Start the DAQ output with `drive` (through the same drive-limit gate)."""
        self.stand.daq.start(limited_drive(drive, self.drive_limit_v))

    def crossfade(self, new_drive: np.ndarray, state: State = State.EQUALISING) -> None:
        """One period moving smoothly from the current drive to `new_drive`, which then plays.
        An abort meanwhile lets the crossfade play, then fades out from `new_drive`: the drive
        never steps at a period boundary."""
        ramp = fade_envelope(self.segment.plan.period_samples, 1, "in")
        self.write(self.drive * (1.0 - ramp) + new_drive * ramp)
        self.in_transition = True
        try:
            self.period(state)
        except BaseException:
            # the crossfade is written (played or queued): a fade-out starts where it ends
            self.drive = new_drive
            raise
        finally:
            self.in_transition = False
        self.drive = new_drive
        self.write(new_drive)

    def fade_out(self) -> None:
        """Raised-cosine fade of the steady drive over a few cycles of the lowest line
        (`fade_out_s`, else dsp.multisine.fade_out_samples), zeros to the period's end, then
        0 V; reads until every faded period has played (a drive queued before it plays first)."""
        self.announce(State.FADING_OUT)
        plan = self.segment.plan
        n = plan.period_samples
        fs = plan.sample_rate_hz
        fade_s = self.settings.fade_out_s
        ramp = (
            max(2, round(fade_s * fs))
            if fade_s is not None
            else fade_out_samples(float(np.min(plan.frequencies_hz)), fs)
        )
        envelope = fade_out_envelope(n, ramp)
        for k in range(envelope.size // n):
            self.write(self.drive * envelope[k * n : (k + 1) * n])
        self.drive = np.zeros(n)
        self.write(self.drive)
        self.in_transition = True
        try:
            while len(self.queue) > 1:  # the zero period stays queued; stop() plays it
                self.period(State.FADING_OUT)
        finally:
            self.in_transition = False

    def try_fade_out(self) -> None:
        """Fade out after a failure, if anything plays and no emergency stop zeroed it."""
        if self.emergency:
            return
        try:
            if np.any(self.drive != 0):
                self.fade_out()
        except Exception:
            pass

    def stop_drive(self) -> float | None:
        """Stop with the output at 0 V, whatever happened; the output voltage as reported."""
        try:
            self.stand.daq.stop()
        except DeviceLostError:
            pass  # a lost device has reset its output
        return self.stand.daq.output_v

    # --- power amplifier ------------------------------------------------------------------

    def enable_power(self) -> None:
        """Switch the power amplifier's output on (the DAQ already plays 0 V); it refuses
        while its interlock is open or it reports a fault (AmplifierFaultError)."""
        amplifier = self.stand.power_amplifier
        if amplifier is None or self.power_on:
            return
        self.power_on = True  # from here, every exit path switches it off
        amplifier.set_output_enabled(True)
        self.log("power amplifier: output on")

    def poll_power(self) -> None:
        """The power amplifier's fault and interlock state, once per period: an over-current,
        an open interlock (over-travel) or a lost session ends the run (HardwareError)."""
        amplifier = self.stand.power_amplifier
        if amplifier is None or not self.power_on or self.power_failed:
            return
        try:
            fault = amplifier.fault()
            if fault is not None:
                raise AmplifierFaultError(f"power amplifier reports a fault: {fault}")
            if not amplifier.interlock_closed():
                raise AmplifierFaultError(
                    "power amplifier interlock open (exciter over-travel or cover open)"
                )
        except HardwareError:
            self.power_failed = True
            raise

    def disable_power(self) -> None:
        """Switch the power amplifier's output off after the drive is at 0 V (every exit
        path); a failure is logged, never raised over the run's own outcome."""
        amplifier = self.stand.power_amplifier
        if amplifier is None or not self.power_on:
            return
        try:
            amplifier.set_output_enabled(False)
            self.power_on = False
            self.log("power amplifier: output off")
        except Exception as exc:
            log.error("power amplifier: output could not be switched off: %s", exc)
            self.log(f"power amplifier: output could not be switched off: {exc}")

    # --- input ------------------------------------------------------------------------------

    def read(self, state: State) -> np.ndarray:
        """Read one period, check it, record it, send it to the listener; the block as read."""
        with self._abort_lock:
            reason = self._abort_reason
        if reason is not None and (self.emergency or not self.in_transition):
            raise Aborted(reason)  # a fade or crossfade already written plays to its end
        period_s = self.segment.plan.period_s
        block = self.stand.daq.read_period(timeout_s=period_s * 2 + 5.0)
        if self.queue:
            self.played = self.queue.popleft()
        played = self.played
        self.periods_read += 1
        if played.size:
            self.peak_played_v = max(self.peak_played_v, float(np.max(np.abs(played))))
        self._count_excitation(played)
        self.poll_power()  # first: a tripped amplifier explains what the channels show
        self._check_block(block)
        if self.writer is not None and not self.recording_full:
            index = self.channel_index
            drive = block[index["drive"]] if "drive" in index else played
            self.writer.append(block[index["reference"]], block[index[self.dut_name]], drive)
            for name, writer in self.member_writers.items():  # the other DUTs of a batch
                writer.append(block[index["reference"]], block[index[name]], drive)
        amplifier = self.stand.measuring_amplifier
        if amplifier is not None and amplifier.overloaded(
            self.stand.config.reference_amplifier_channel
        ):
            raise OverloadError(
                "measuring amplifier reports an overload on the reference channel",
                channel="reference",
            )
        self.emit(
            PeriodBlock(
                self.periods_read,
                state,
                tuple(self.channel_index),
                block,
                played,
                ranges_v=dict(self.ranges),
            )
        )
        return block

    def period(self, state: State) -> tuple[np.ndarray, np.ndarray]:
        """Read one period (see `read`); line spectra of (reference, DUT)."""
        lines = self.segment.lines(self.pair(self.read(state)))
        return lines[0], lines[1]

    def _check_block(self, block: np.ndarray) -> None:
        for name, index in self.channel_index.items():
            x = block[index]
            if not np.all(np.isfinite(x)):
                raise ProcedureError(
                    f"{name} channel: NaN or inf samples from the DAQ; check the driver and cabling"
                )
            if name == "drive":
                continue
            limit = OVERLOAD_FRACTION * self.ranges[name]
            over = int(np.count_nonzero(np.abs(x) >= limit))
            if over:
                raise InputRangeOverload(
                    f"{name} channel: {over} sample(s) at its +-{self.ranges[name]:g} V range "
                    "limit",
                    channel=name,
                )

    def settle(self, noise: np.ndarray, state: State = State.EQUALISING) -> Settled:
        """Read periods until two consecutive ones agree at every line on both channels (the
        DUT can carry a transient of its own, e.g. a piezo's 0.5 Hz high-pass); the table
        acceleration per line from the reference channel, averaged over the two. Agreement:
        within `settle_tolerance` of the line or 6 `noise` standard deviations (V, per period,
        shape (2, lines) of the segment), plus what a tone beside the line changes there
        (hum a little off a bin while driven: it never settles; dsp.tones, issue 32). A line
        with a tone within a fifth of a bin whose change has stopped shrinking for
        `STEADY_PAIRS` pairs (a hum, not a transient, which decays) is left out of the test:
        the acquisition measures it and flags the line as not separable."""
        s = self.settings
        previous = previous_block = previous_spectra = None
        excess = interference = None
        leaks: list[LineLeak] = []
        bins = self.segment.plan.bins
        steady = np.zeros(bins.size, dtype=int)  # pairs a tone on the line has not decayed
        last_change: np.ndarray | None = None
        for _ in range(s.max_settle_periods):
            block = self.read(state)
            pair = self.pair(block)
            if self.segment.one_line:
                spectra, lines = None, self.segment.lines(pair)
            else:  # every bin: a tone beside a line is told from a transient (issue 32)
                spectra = period_spectrum(pair)
                lines = spectra[:, bins]
            ref, dut = lines[0], lines[1]
            if previous is not None:
                interference = None
                if spectra is not None and previous_spectra is not None:
                    leaks = [line_leak(spectra[c] - previous_spectra[c], bins) for c in (0, 1)]
                    interference = np.array([np.where(k.separable, k.leak_v, 0.0) for k in leaks])
                tolerance = s.settle_tolerance
                excess = settle_excess(previous, lines, noise, tolerance, interference)
                change = np.max(np.abs(lines - previous), axis=0)
                if leaks:
                    on_line = ~(leaks[0].separable & leaks[1].separable)
                    holding = last_change is not None and change >= STEADY_RATIO * last_change
                    steady = np.where(on_line & holding, steady + 1, 0)
                last_change = change
                hummed = steady >= STEADY_PAIRS
                if np.all((excess <= 0) | hummed[None, :]):
                    assert previous_block is not None
                    if interference is not None and np.any(interference > 0):
                        self.log(_hum_note(self.segment.plan, leaks, interference, lines))
                    for k in np.flatnonzero(hummed & np.any(excess > 0, axis=0)):
                        self.log(
                            f"settle: line {self.segment.plan.lines[k].label} left out: a tone "
                            f"at {_tone_hz(self.segment.plan, leaks, int(k)):.4g} Hz on it "
                            "does not decay (hum while driven?); measured in the acquisition"
                        )
                    return Settled(
                        self.to_acceleration((ref + previous[0]) / 2),
                        (ref, dut),
                        (previous_block, block),
                    )
            previous, previous_block, previous_spectra = lines, block, spectra
        named = _unsettled_hum(self.segment.plan, leaks, excess, previous)
        raise ProcedureError(
            f"the table did not settle within {s.max_settle_periods} periods (consecutive "
            + (
                f"periods still differ): {named}"
                if named
                else "periods still differ): check for a loose mount, a resonance or an "
                "unstable amplifier"
            )
        )

    def to_acceleration(self, reference_lines: np.ndarray) -> np.ndarray:
        """Table acceleration (complex, m/s^2) from the reference channel's line spectra (V)."""
        chain = self.stand.chain
        magnitude, phase = chain.sensitivity_at(self.segment.plan.frequencies_hz)
        volts_per_ms2 = magnitude * 1e-3 * chain.reference_gain * np.exp(1j * np.radians(phase))
        return reference_lines / volts_per_ms2


STEADY_PAIRS = 3  # pairs of periods a tone on a line must not decay to be taken for hum
STEADY_RATIO = 0.8  # "not decaying": the change keeps at least this fraction of the last one


def _hum_note(
    plan: Plan, leaks: list[LineLeak], interference: np.ndarray, lines: np.ndarray
) -> str:
    """run.log's note that a tone beside lines was allowed for in the settle test."""
    worst = np.nanargmax(np.max(interference / np.maximum(np.abs(lines), 1e-300), axis=0))
    tone = _tone_hz(plan, leaks, int(worst))
    return (
        f"settle: a tone at {tone:.4g} Hz beside line {plan.lines[worst].label} (hum while "
        "driven?) changes from period to period; allowed for, it is measured and carried in "
        "the budget"
    )


def _tone_hz(plan: Plan, leaks: list[LineLeak], k: int) -> float:
    """The nearest tone to line k in either channel's period-to-period change (Hz)."""
    positions = [leak.tone_bin[k] for leak in leaks if np.isfinite(leak.tone_bin[k])]
    if not positions:
        return math.nan
    m = plan.bins[k]
    return float(min(positions, key=lambda p: abs(p - m))) * plan.resolution_hz


def _unsettled_hum(
    plan: Plan,
    leaks: list[LineLeak],
    excess: np.ndarray | None,
    lines: np.ndarray | None,
) -> str:
    """What keeps a line from settling when it is a tone beside it (hum a little off a bin,
    e.g. while driven: a power-amplifier ground loop), naming the line and the tone; "" when
    no tone sits within a bin of a line that failed."""
    if excess is None or not leaks or lines is None:
        return ""
    failing = np.flatnonzero(np.any(excess > 0, axis=0))
    named = []
    for k in failing:
        tone = _tone_hz(plan, leaks, int(k))
        if not math.isfinite(tone) or abs(tone - plan.frequencies_hz[k]) > plan.resolution_hz:
            continue
        named.append(
            f"line {plan.lines[k].label} ({plan.frequencies_hz[k]:g} Hz) with a tone at "
            f"{tone:.4g} Hz"
        )
    if not named:
        return ""
    return (
        f"{'; '.join(named)}: hum (mains hum while driven, e.g. a power-amplifier ground loop) "
        f"within a bin of the line turns against it from period to period and cannot be told "
        "from it; remove the hum (ground loop), or change the period or the line"
    )
