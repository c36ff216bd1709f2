"""A stored recording read a slice at a time (issue 34 point 4: memory flat with the record).

`StoredSignal` stands for one channel of an HDF5 recording: it knows its length and reads the
samples a slice asks for from the file (h5py slicing of the stored dataset), so an analysis
that walks the periods in batches holds one batch, not the record. `SampleScan` checks a
channel block by block (non-finite samples, a flat dead channel, samples at the range limit or
a clipped flat top) and states exactly what the whole-array check of app.io.hdf5.validate
states: that check is this scan over a single block. Volts throughout.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from app.io.hdf5_fields import RecordingError

BLOCK_SAMPLES = 1 << 18  # samples per read when a stored channel is scanned (2 MiB of float64)
OVERLOAD_FRACTION = 0.995  # a sample within 0.5 % of the range is at its limit (SPEC s.11)
FLAT_TOP_RUN = 5  # without a known range: this many equal samples at the extreme = clipped
READ_ERRORS = (OSError, KeyError, RuntimeError, ValueError, TypeError)


def file_stamp(path: Path) -> tuple[int, int, int]:
    """What tells a changed file: size (bytes), modification time (ns) and inode."""
    st = os.stat(path)
    return st.st_size, st.st_mtime_ns, st.st_ino


@contextmanager
def kept_open(handle: h5py.File, *, keep: bool) -> Iterator[h5py.File]:
    """`handle` for a `with` block: closed when the block raises, and at its end unless
    `keep` (a stored recording's channels go on reading through it)."""
    try:
        yield handle
    except BaseException:
        handle.close()
        raise
    if not keep:
        handle.close()


class StoredFile:
    """An HDF5 recording opened read-only on first use and kept open while its channels are
    in use (one opening per analysis, not one per slice); closed with `close` or when the
    last channel referring to it is gone. A file changed on disk after it was opened (HDF5
    would read zeros past a cut) is refused at the next read: its size, modification time
    and inode are compared before each."""

    def __init__(
        self,
        path: Path,
        opened: h5py.File | None = None,
        stamp: tuple[int, int, int] | None = None,
    ):
        self.path = Path(path)
        self._file = opened  # the reader's own opening, when it handed it over
        self._stamp = stamp if opened is not None else None  # taken before `opened` was

    def dataset(self, name: str) -> h5py.Dataset:
        if self._file is None or not self._file.id.valid or self._stamp is None:
            self._stamp = file_stamp(self.path)
            self._file = h5py.File(self.path, "r")
        elif file_stamp(self.path) != self._stamp:
            self.close()
            raise OSError("the file changed on disk while it was read; analyse it again")
        return self._file[name]

    def close(self) -> None:
        if self._file is not None and self._file.id.valid:
            self._file.close()
        self._file = None


class StoredSignal:
    """One channel of an HDF5 recording (V, float64), `size` samples of dataset `dataset` of
    `file`, read on demand: slicing (step 1) returns a numpy array of that slice. A read the
    file refuses (cut, corrupt, replaced) is a RecordingError naming the file and dataset."""

    ndim = 1
    dtype = np.dtype(np.float64)

    def __init__(self, file: StoredFile, dataset: str, size: int, label: str):
        self.file = file
        self.dataset = dataset
        self.size = int(size)
        self.label = label  # "recording.h5: /signals/dut"

    @property
    def shape(self) -> tuple[int]:
        return (self.size,)

    def __len__(self) -> int:
        return self.size

    def __repr__(self) -> str:
        return f"StoredSignal({self.label}, {self.size} samples)"

    def __getitem__(self, key: slice) -> np.ndarray:
        if not isinstance(key, slice):
            raise TypeError(f"{self.label}: read by slices of samples, not {key!r}")
        start, stop, step = key.indices(self.size)
        if step != 1:
            raise TypeError(f"{self.label}: read by contiguous slices (step 1), not step {step}")
        if stop <= start:
            return np.empty(0)
        try:
            data = self.file.dataset(self.dataset)[start:stop]
        except READ_ERRORS as exc:
            self.file.close()
            raise RecordingError(f"{self.label}: cannot be read ({exc})") from None
        if data.shape != (stop - start,):
            raise RecordingError(
                f"{self.label}: {data.size} samples read where {stop - start} were stored "
                "(the file changed since it was checked)"
            )
        return np.asarray(data, dtype=float)

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        """The whole channel in memory (for code that needs all of it at once)."""
        data = self[:]
        return data if dtype is None else data.astype(dtype)

    def blocks(self, samples: int | None = None) -> Iterator[np.ndarray]:
        """The channel in consecutive blocks of at most `samples` (default BLOCK_SAMPLES)."""
        samples = samples or BLOCK_SAMPLES
        for start in range(0, self.size, samples):
            yield self[start : start + samples]


def channel_blocks(x: np.ndarray | StoredSignal) -> Iterator[np.ndarray]:
    """A channel's samples in blocks: a stored one read a block at a time, an array whole."""
    if isinstance(x, StoredSignal):
        yield from x.blocks()
    else:
        yield np.asarray(x, dtype=float)


class _ExtremeRun:
    """The longest run of samples equal to the channel's maximum (`sign` 1) or minimum (-1),
    over blocks seen in order: a run may continue across a block boundary, and a new
    extreme restarts the count."""

    def __init__(self, sign: int):
        self.sign = sign
        self.value = math.nan
        self.longest = 0
        self.tail = 0  # the run of extreme samples ending the blocks seen so far

    def add(self, block: np.ndarray) -> None:
        v = float(block.max() if self.sign > 0 else block.min())
        if math.isnan(self.value) or self.sign * (v - self.value) > 0:
            self.value, self.longest, self.tail = v, 0, 0
        if v != self.value:
            self.tail = 0
            return
        padded = np.zeros(block.size + 2, dtype=np.int8)  # int8: 2 bytes a sample
        padded[1:-1] = block == self.value
        edges = np.flatnonzero(np.diff(padded))
        starts, ends = edges[::2], edges[1::2]
        lengths = ends - starts
        if starts[0] == 0:
            lengths[0] += self.tail
        self.longest = max(self.longest, int(lengths.max()))
        self.tail = int(lengths[-1]) if ends[-1] == block.size else 0


class SampleScan:
    """The sample checks of one channel, fed block by block (`add`), then `check` raises the
    RecordingError the first failing check states: non-finite samples, then (not for the
    drive) a flat channel, then samples at the range limit `range_v` (V; 0: unknown range,
    then a flat top of FLAT_TOP_RUN equal samples at the maximum, then the minimum)."""

    def __init__(self, channel: str, where: str, name: str, range_v: float = 0.0):
        self.channel, self.where, self.name = channel, where, name
        self.range_v = range_v if math.isfinite(range_v) and range_v > 0 else 0.0
        self.seen = 0
        self.first = math.nan
        self.bad = 0
        self.first_bad: tuple[int, str] | None = None
        self.low, self.high = math.inf, -math.inf
        self.at_limit = 0
        self.first_at_limit = -1
        self.runs = (_ExtremeRun(1), _ExtremeRun(-1))

    def add(self, block: np.ndarray) -> None:
        if block.size == 0:
            return
        if self.seen == 0:
            self.first = float(block[0])
        bad = np.flatnonzero(~np.isfinite(block))
        if bad.size:
            if self.first_bad is None:
                kind = "NaN" if np.isnan(block[bad[0]]) else "inf"
                self.first_bad = (self.seen + int(bad[0]), kind)
            self.bad += int(bad.size)
        elif self.first_bad is None and self.channel != "drive":
            self.low = min(self.low, float(block.min()))
            self.high = max(self.high, float(block.max()))
            if self.range_v:
                limit = np.flatnonzero(np.abs(block) >= OVERLOAD_FRACTION * self.range_v)
                if limit.size and self.first_at_limit < 0:
                    self.first_at_limit = self.seen + int(limit[0])
                self.at_limit += int(limit.size)
            else:
                for run in self.runs:
                    run.add(block)
        self.seen += block.size

    def check(self) -> None:
        name, where = self.name, self.where
        if self.first_bad is not None:
            index, kind = self.first_bad
            raise RecordingError(
                f"{name}: {where}: {self.bad} non-finite sample(s), first {kind} at sample {index}"
            )
        if self.channel == "drive":
            return
        if self.high - self.low == 0.0:
            raise RecordingError(
                f"{name}: {where}: flat at {self.first:g} V: dead channel or not connected"
            )
        if self.range_v:
            if self.at_limit:
                raise RecordingError(
                    f"{name}: {where}: {self.at_limit} sample(s) at the +-{self.range_v:g} V "
                    f"range limit, first at sample {self.first_at_limit}: overload; lower the "
                    "level or raise the channel range"
                )
            return
        for run in self.runs:
            if run.longest >= FLAT_TOP_RUN:
                raise RecordingError(
                    f"{name}: {where}: {run.longest} consecutive samples at {run.value:g} V: "
                    "clipped at its range limit (overload); lower the level or raise the range"
                )
