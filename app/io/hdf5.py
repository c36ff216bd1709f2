"""The recording format: raw channels in volts plus everything needed to re-analyse them.

HDF5 layout (format "accelcal-recording", version 1):

    /                 attrs: format, format_version, sample_rate_hz, period_samples,
                             settle_periods, acquired_periods (optional: periods analysed
                             after the settle periods; later ones, e.g. a fade-out, are kept
                             but not analysed), created_utc, software_version,
                             status ("complete" or "aborted", set when the recording ends;
                             absent: the run never finished, the recording is "incomplete"),
                             status_reason (why it was aborted)
    /signals/reference  float64 V, chunked one period, resizable; attrs unit, range_v (0 = unknown)
    /signals/dut        idem
    /signals/drive      idem, optional (the DAQ output)
    /config           attrs (JSON text): plan, reference_chain, budget, cmc (optional: the
                      laboratory's CMC bands, dsp.cmc; absent when the stand stated none)
    /truth            optional (simulated recordings): datasets frequency_hz,
                      sensitivity_mv_per_ms2, phase_deg at the line frequencies; attrs describe
                      the simulated DUT and level

A malformed recording (missing dataset, wrong length, NaN/inf, a flat dead channel, samples at
a channel's range limit) is refused with a RecordingError that names the file, the channel and
the problem. CSV import lives in app.io.csv, TDMS in app.io.tdms; both give a Recording.
"""

from __future__ import annotations

import dataclasses
import errno
import json
import logging
import math
import os
import resource
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from app.io import hdf5_fields as fields
from app.io.checks import MAX_HDF5_BYTES, InputFileError, check_input_file
from app.io.hdf5_fields import RecordingError
from app.io.hdf5_stream import (
    SampleScan,
    StoredFile,
    StoredSignal,
    channel_blocks,
    file_stamp,
    kept_open,
)
from app.io.vocabulary import Mode, RunStatus
from app.version import software_version
from dsp.calibration import ReferenceChain
from dsp.cmc import Cmc
from dsp.multisine import Plan
from dsp.uncertainty import Budget

FORMAT_NAME = "accelcal-recording"
FORMAT_VERSION = 1
CHANNELS = ("reference", "dut")

log = logging.getLogger(__name__)

HEADROOM_PERIODS = 4  # a recording stops this many periods before the disk or file limit
HEADROOM_FIXED_BYTES = 256 * 1024  # plus this much (HDF5 metadata, status, results, manifest)


class DiskFullError(OSError):
    """The recording's disk (or the process's file-size limit) has no room for another period.

    Raised before HDF5 is asked to write what it could not, so the file stays readable up to
    its last flushed period."""

    def __init__(self, message: str):
        super().__init__(errno.ENOSPC, message)

    def __str__(self) -> str:
        return str(self.strerror)


def _is_disk_full(exc: OSError) -> bool:
    """ENOSPC or EFBIG, from the OS or quoted in an HDF5 message ("errno = 28")."""
    codes = (errno.ENOSPC, errno.EFBIG)
    if getattr(exc, "errno", None) in codes:
        return True
    return any(f"errno = {code}," in str(exc) for code in codes)


def free_bytes(path: Path) -> float:
    """Bytes a file at `path` (existing or not) may still grow by: the smaller of the free space
    of its file system (statvfs, unprivileged) and what RLIMIT_FSIZE leaves it; inf if unknown."""
    room = math.inf
    folder = path if path.is_dir() else path.parent
    try:
        st = os.statvfs(folder)
        room = float(st.f_bavail) * float(st.f_frsize)
    except OSError:
        pass
    soft, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
    if soft != resource.RLIM_INFINITY:
        try:
            size = path.stat().st_size
        except OSError:
            size = 0
        room = min(room, float(soft - size))
    return room


@dataclass(frozen=True)
class Truth:
    """The true DUT sensitivity at the line frequencies (simulated recordings only)."""

    frequency_hz: np.ndarray
    sensitivity_mv_per_ms2: np.ndarray
    phase_deg: np.ndarray
    attrs: dict[str, Any] = field(default_factory=dict)


Samples = np.ndarray | StoredSignal  # a channel in memory, or stored and read a slice at a time


@dataclass(frozen=True)
class Recording:
    """A two-channel recording (volts), with its analysis context. Its channels are held in
    memory, or (`read_recording(..., stored=True)`) read from the file a slice at a time."""

    sample_rate_hz: float
    period_samples: int
    reference_v: Samples
    dut_v: Samples
    plan: Plan
    chain: ReferenceChain
    budget: Budget
    settle_periods: int = 0
    drive_v: Samples | None = None
    ranges_v: dict[str, float] = field(default_factory=dict)
    source: str = ""
    truth: Truth | None = None
    acquired_periods: int | None = None
    status: RunStatus | None = None  # None: not recorded by this program (CSV, in memory)
    cmc: Cmc | None = None  # the laboratory's CMC (the stand's, or --budget's [[cmc]])
    # the run's blocking warnings of lines too few LSB above the converter's step: the lines a
    # re-analysis does not state either (dsp.not_stated)
    resolution_warnings: tuple[str, ...] = ()

    @property
    def periods(self) -> int:
        """Whole periods in the recording, settle periods included."""
        return self.reference_v.size // self.period_samples

    @property
    def analysed_periods(self) -> int:
        """Whole periods the analysis uses: after the settle periods, at most `acquired_periods`."""
        left = max(self.periods - self.settle_periods, 0)
        return left if self.acquired_periods is None else min(left, max(self.acquired_periods, 0))

    def analysis_periods(self) -> tuple[np.ndarray, np.ndarray]:
        """Reference and DUT as (periods, N) arrays, settle periods skipped (views of channels
        in memory; a stored recording's are read whole: `iter_batches` reads them in batches)."""
        return self.period_range(0, self.analysed_periods)

    def period_range(self, first: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """Analysed periods `first` .. `stop` - 1 of reference and DUT, shape (periods, N)."""
        n = self.period_samples
        start = (self.settle_periods + first) * n
        end = (self.settle_periods + stop) * n
        ref = self.reference_v[start:end].reshape(-1, n)
        dut = self.dut_v[start:end].reshape(-1, n)
        return ref, dut


class RecordingWriter:
    """Appends periods to an HDF5 recording and flushes after each, so a cut run stays readable."""

    def __init__(
        self,
        path: str | Path,
        plan: Plan,
        chain: ReferenceChain,
        budget: Budget,
        *,
        settle_periods: int = 0,
        with_drive: bool = False,
        ranges_v: dict[str, float] | None = None,
        created_utc: str | None = None,
        cmc: Cmc | None = None,
    ):
        self.path = Path(path)
        self._period_bytes = 8 * 3 * int(plan.period_samples)  # float64, up to three channels
        self._check_room()
        self._file = h5py.File(self.path, "w")
        f = self._file
        f.attrs["format"] = FORMAT_NAME
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["sample_rate_hz"] = plan.sample_rate_hz
        f.attrs["period_samples"] = plan.period_samples
        f.attrs["settle_periods"] = int(settle_periods)
        f.attrs["created_utc"] = created_utc or datetime.now(UTC).isoformat(timespec="seconds")
        f.attrs["software_version"] = software_version()
        config = f.create_group("config")
        config.attrs["plan"] = json.dumps(plan.to_dict())
        config.attrs["reference_chain"] = json.dumps(chain.to_dict())
        config.attrs["budget"] = json.dumps(budget.to_list())
        if cmc is not None:
            config.attrs["cmc"] = json.dumps(cmc.to_list())
        signals = f.create_group("signals")
        names = (*CHANNELS, "drive") if with_drive else CHANNELS
        ranges_v = ranges_v or {}
        self._datasets = {}
        for name in names:
            ds = signals.create_dataset(
                name,
                shape=(0,),
                maxshape=(None,),
                dtype="f8",
                chunks=(plan.period_samples,),
            )
            ds.attrs["unit"] = "V"
            ds.attrs["range_v"] = float(ranges_v.get(name, 0.0))
            self._datasets[name] = ds

    def append(self, reference_v: np.ndarray, dut_v: np.ndarray, drive_v=None) -> None:
        """Append samples (volts) of every channel and flush to disk."""
        blocks = {"reference": reference_v, "dut": dut_v}
        if "drive" in self._datasets:
            if drive_v is None:
                raise ValueError("recording: this file has a drive channel; give drive_v")
            blocks["drive"] = drive_v
        lengths = {np.asarray(b).size for b in blocks.values()}
        if len(lengths) != 1:
            raise ValueError("recording: every channel needs the same number of samples")
        self._period_bytes = max(self._period_bytes, 8 * len(blocks) * lengths.pop())
        self._check_room()
        try:
            for name, block in blocks.items():
                ds = self._datasets[name]
                start = ds.shape[0]
                ds.resize((start + np.asarray(block).size,))
                ds[start:] = block
            self._file.flush()
        except OSError as exc:
            if _is_disk_full(exc):
                raise DiskFullError(f"{self.path}: {exc}") from exc
            raise

    def _check_room(self) -> None:
        """DiskFullError unless the disk and the file-size limit leave room for a few more
        periods (`HEADROOM_PERIODS`) plus `HEADROOM_FIXED_BYTES`."""
        needed = HEADROOM_PERIODS * self._period_bytes + HEADROOM_FIXED_BYTES
        room = free_bytes(self.path)
        if room < needed:
            raise DiskFullError(
                f"{room / 1e6:.2f} MB left for {self.path.name}, a period needs "
                f"{self._period_bytes / 1e6:.2f} MB and {needed / 1e6:.2f} MB are kept free; "
                "the recording stops at its last complete period"
            )

    def set_settle_periods(self, periods: int) -> None:
        """Mark how many leading periods the analysis skips (background, fades, settling)."""
        self._file.attrs["settle_periods"] = int(periods)
        self._file.flush()

    def set_mode(self, mode: Mode) -> None:
        """Mark the excitation (multisine by default; stepped-sine blocks vary in length)."""
        self._file.attrs["mode"] = Mode(mode).value
        self._file.flush()

    def set_acquired_periods(self, periods: int) -> None:
        """Mark how many periods after the settle periods the analysis uses."""
        self._file.attrs["acquired_periods"] = int(periods)
        self._file.flush()

    def widen_ranges(self, ranges_v: dict[str, float]) -> None:
        """A run re-ranged (issue 32): each channel's stored range (V) becomes the larger of the
        two, so a re-read's overload check never flags what the wider range held."""
        for name, value in ranges_v.items():
            ds = self._datasets.get(name)
            if ds is not None:
                ds.attrs["range_v"] = max(float(ds.attrs["range_v"]), float(value))
        self._file.flush()

    def set_budget(self, budget: Budget) -> None:
        """Store the budget as used (e.g. with the background measured at the start)."""
        self._file["config"].attrs["budget"] = json.dumps(budget.to_list())
        self._file.flush()

    def set_resolution_warnings(self, warnings: Sequence[str]) -> None:
        """Store the run's "too few LSB" warnings (the lines it does not state: issue 32 point
        2), so a re-analysis of the recording states the same lines as the run."""
        self._file["config"].attrs["resolution_warnings"] = json.dumps(list(warnings))
        self._file.flush()

    def set_status(self, status: RunStatus, reason: str | None = None) -> bool:
        """Mark how the recording ended (a RunStatus; aborted with its reason). Never raises
        for the file: False (logged) when it cannot take the mark, which leaves the recording
        "incomplete", the safe reading."""
        if status not in tuple(RunStatus):
            raise ValueError(f"recording status: {status!r} is not one of {', '.join(RunStatus)}")
        status = RunStatus(status)
        problem = None if self._file.id.valid else "the recording is closed"
        if problem is None:
            try:
                self._file.attrs["status"] = status.value
                self._file.attrs["status_reason"] = reason or ""
                self._file.flush()
            except (OSError, KeyError, ValueError, RuntimeError) as exc:  # the disk refused it
                problem = str(exc)
        if problem is not None:
            log.warning("%s: recording status %r not stored: %s", self.path, status.value, problem)
            return False
        return True

    def write_truth(self, truth: Truth) -> None:
        """Store the simulated truth (group /truth)."""
        group = self._file.require_group("truth")
        for name in ("frequency_hz", "sensitivity_mv_per_ms2", "phase_deg"):
            if name in group:
                del group[name]
            group.create_dataset(name, data=np.asarray(getattr(truth, name), dtype=float))
        for key, value in truth.attrs.items():
            group.attrs[key] = value
        self._file.flush()

    def close(self) -> None:
        if self._file.id.valid:
            self._file.close()

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_recording(path: str | Path, recording: Recording) -> None:
    """Write a whole in-memory recording to HDF5."""
    with RecordingWriter(
        path,
        recording.plan,
        recording.chain,
        recording.budget,
        settle_periods=recording.settle_periods,
        with_drive=recording.drive_v is not None,
        ranges_v=recording.ranges_v,
        cmc=recording.cmc,
    ) as writer:
        drive = None if recording.drive_v is None else np.asarray(recording.drive_v)
        writer.append(np.asarray(recording.reference_v), np.asarray(recording.dut_v), drive)
        if recording.truth is not None:
            writer.write_truth(recording.truth)
        writer.set_status(recording.status or RunStatus.COMPLETE)  # written whole


def read_recording(
    path: str | Path, *, stored: bool = False, dut_channel: str = "dut"
) -> Recording:
    """Read and validate an HDF5 recording of this program; RecordingError names the file and
    the dataset or attribute that is not what this program writes (app.io.hdf5_fields). With
    `stored` the channels stay in the file (StoredSignal: validated here a block at a time,
    read a slice at a time by the analysis), so memory does not grow with the record.
    `dut_channel`: the DUT channel read as the recording's DUT (a batch recording of several
    DUTs, issue 36, holds "dut.<position>" channels)."""
    path = Path(path)
    name = path.name
    try:
        check_input_file(path, MAX_HDF5_BYTES, "HDF5 recording")
    except InputFileError as exc:
        raise RecordingError(str(exc)) from None
    try:
        stamp = file_stamp(path) if stored else None  # before opening: a change after shows
        handle = h5py.File(path, "r")
    except FileNotFoundError:
        raise RecordingError(f"{path}: no such file") from None
    except OSError as exc:
        raise RecordingError(f"{name}: not a readable HDF5 file ({exc})") from None
    with kept_open(handle, keep=stored) as f:  # stored: its channels are read through it
        head = fields.read_head(f, name, FORMAT_NAME, FORMAT_VERSION)
        config = fields.group(f, "config", name)
        assert config is not None
        where = f"{name}: /config attribute"
        plan = fields.json_attr(config.attrs, "plan", where, fields.plan_from)
        chain = fields.json_attr(config.attrs, "reference_chain", where, fields.chain_from)
        budget = fields.json_attr(config.attrs, "budget", where, Budget.from_list)
        cmc = fields.json_attr(config.attrs, "cmc", where, Cmc.from_list)
        for key, value in (("plan", plan), ("reference_chain", chain), ("budget", budget)):
            if value is None:
                raise RecordingError(f"{name}: missing /config attribute '{key}'")
        assert plan is not None and chain is not None and budget is not None
        resolution_warnings = fields.json_attr(
            config.attrs, "resolution_warnings", where, _text_list
        )
        fields.group(f, "signals", name)
        stored_file = StoredFile(path, f, stamp) if stored else None
        signals: dict[str, Samples] = {}
        ranges: dict[str, float] = {}
        for key, channel in (("reference", "reference"), ("dut", dut_channel), ("drive", "drive")):
            label = f"{name}: /signals/{channel}"
            ds = fields.float_dataset(f, f"signals/{channel}", name, optional=channel == "drive")
            if ds is None:
                continue
            unit = fields.text_attr(ds.attrs, "unit", f"{label} attribute")
            if unit not in (None, "V"):
                raise RecordingError(f"{label} attribute 'unit': {unit!r}, expected 'V' (volts)")
            if stored_file is not None:
                signals[key] = StoredSignal(stored_file, f"signals/{channel}", ds.size, label)
            else:
                signals[key] = np.asarray(ds[()], dtype=float)
            stored_range = fields.number_attr(
                ds.attrs, "range_v", f"{label} attribute", low=0.0, high=1e6
            )
            ranges[key] = stored_range or 0.0
        status = recording_status(f.attrs.get("status"))
        truth = _read_truth(f, name)
    if plan.sample_rate_hz != head.sample_rate_hz or plan.period_samples != head.period_samples:
        raise RecordingError(
            f"{name}: attribute 'sample_rate_hz' {head.sample_rate_hz:g} Hz and "
            f"'period_samples' {head.period_samples} disagree with /config attribute 'plan' "
            f"({plan.sample_rate_hz:g} Hz, {plan.period_samples} samples)"
        )
    recording = Recording(
        sample_rate_hz=head.sample_rate_hz,
        period_samples=head.period_samples,
        reference_v=signals["reference"],
        dut_v=signals["dut"],
        drive_v=signals.get("drive"),
        plan=plan,
        chain=chain,
        budget=budget,
        settle_periods=head.settle_periods,
        ranges_v=ranges,
        source=str(path),
        truth=truth,
        resolution_warnings=resolution_warnings or (),
        acquired_periods=head.acquired_periods,
        status=status,
        cmc=cmc,
    )
    labels = {c: f"/signals/{dut_channel if c == 'dut' else c}" for c in signals}
    validate(recording, name, labels=labels)
    return recording


def recording_status(mark: object) -> RunStatus:
    """A recording's status from its "status" attribute: "complete" or "aborted" as marked,
    anything else (no mark: the run never finished) "incomplete"."""
    if isinstance(mark, bytes):
        mark = mark.decode("utf-8", "replace")
    if isinstance(mark, str) and mark in (RunStatus.COMPLETE, RunStatus.ABORTED):
        return RunStatus(str(mark))
    return RunStatus.INCOMPLETE


def _text_list(value: object) -> tuple[str, ...]:
    """A JSON list of texts (ValueError naming what it is instead)."""
    if not isinstance(value, list) or not all(isinstance(t, str) for t in value):
        raise ValueError(f"'resolution_warnings' must be a list of texts, got {value!r:.80}")
    return tuple(value)


TRUTH_DATASETS = ("frequency_hz", "sensitivity_mv_per_ms2", "phase_deg")


def _read_truth(f: h5py.File, name: str) -> Truth | None:
    """The simulated truth (/truth: three 1-D float datasets of one length, finite,
    frequencies > 0), or None when the recording has none."""
    group = fields.group(f, "truth", name, optional=True)
    if group is None:
        return None
    values: dict[str, np.ndarray] = {}
    for key in TRUTH_DATASETS:
        label = f"{name}: /truth/{key}"
        ds = fields.float_dataset(f, f"truth/{key}", name)
        assert ds is not None
        data = np.asarray(ds[()], dtype=float)
        if data.size == 0 or not np.all(np.isfinite(data)):
            raise RecordingError(f"{label}: {data.size} values, expected one finite per line")
        if key == "frequency_hz" and not np.all(data > 0):
            raise RecordingError(f"{label}: frequencies must be > 0 Hz")
        if values and data.size != next(iter(values.values())).size:
            raise RecordingError(f"{label}: {data.size} values where /truth/frequency_hz has "
                                 f"{values['frequency_hz'].size}")  # fmt: skip
        values[key] = data
    attrs = {k: _attr_value(v) for k, v in group.attrs.items()}
    return Truth(**values, attrs=attrs)


def _attr_value(value: Any) -> Any:
    """An attribute as a plain Python value (a scalar, text or a list)."""
    if isinstance(value, np.ndarray):
        return value.reshape(()).item() if value.size == 1 else value.tolist()
    return value.item() if isinstance(value, np.generic) else value


def merge_skew(
    chain: ReferenceChain, file_skew_s: float | None, name: str, where: str
) -> ReferenceChain:
    """The chain with the skew a file states (s; None: it states none) when --skew gave none;
    RecordingError when both are given and disagree. `where` describes the file's statement,
    with '{:g}' for its value."""
    if file_skew_s is None:
        return chain
    if chain.skew_s is None:
        return dataclasses.replace(chain, skew_s=file_skew_s)
    if not math.isclose(chain.skew_s, file_skew_s, rel_tol=1e-9, abs_tol=1e-15):
        raise RecordingError(
            f"{name}: --skew {chain.skew_s:g} s disagrees with {where.format(file_skew_s)}; "
            "give one of them"
        )
    return chain


def validate(recording: Recording, name: str, *, labels: dict[str, str] | None = None) -> None:
    """Refuse a malformed recording with a message naming the channel and the problem;
    `labels` name each channel's source (an HDF5 file's datasets: /signals/dut). A stored
    channel is checked a block at a time (app.io.hdf5_stream.SampleScan), with the same
    statements as a channel in memory."""
    n = recording.period_samples
    channels: dict[str, Samples] = {"reference": recording.reference_v, "dut": recording.dut_v}
    if recording.drive_v is not None:
        channels["drive"] = recording.drive_v
    labels = labels or {}

    def where(channel: str) -> str:
        label = labels.get(channel)
        return f"{label}: channel {channel}" if label else f"channel {channel}"

    lengths = {channel: x.size for channel, x in channels.items()}
    if len(set(lengths.values())) != 1:
        detail = ", ".join(f"{labels.get(c, c)} {v}" for c, v in lengths.items())
        raise RecordingError(f"{name}: channels have different lengths ({detail} samples)")
    length = lengths["reference"]
    if length % n:
        named = ", ".join(labels.get(c, c) for c in channels)
        raise RecordingError(
            f"{name}: {named}: {length} samples is not a whole number of periods of {n} "
            f"samples ({length / n:.3f} periods)"
        )
    for channel, x in channels.items():
        scan = SampleScan(channel, where(channel), name, recording.ranges_v.get(channel, 0.0))
        for block in channel_blocks(x):
            scan.add(block)
        scan.check()


def iter_batches(
    recording: Recording, periods_per_batch: int = 16
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """(reference, DUT) batches of whole analysis periods, shape (periods, N); a stored
    recording's are read from the file one batch at a time."""
    total = recording.analysed_periods
    for start in range(0, total, periods_per_batch):
        yield recording.period_range(start, min(start + periods_per_batch, total))
