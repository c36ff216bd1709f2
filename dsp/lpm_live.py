"""The LPM of a live run's growing record (issue 34): work per added period bounded, memory
independent of the record's length, the results those of `analyze` of the run's recording.

A record of at most WHOLE_RECORD_PERIODS periods is estimated whole after every period
(dsp.lpm_record.record_estimate, exactly as before). A longer record's DFT bins move with its
length (bin k = P m + c of a record of P periods), so its estimate cannot be updated period by
period; it is estimated at checkpoints instead, by the batched estimator `analyze` uses
(dsp.lpm_record.BatchedRecord, fed the 16-period batches app.io.hdf5.iter_batches reads, so
bit-identical to it). The next checkpoint is chosen when the last one is estimated: where the
worst type A is expected to reach the target (type A falls as 1/sqrt(periods)), at least
1 + MIN_GROWTH and at most 1 + MAX_GROWTH times the record so far, and never past the run's
last period. Its accumulator is fed while the periods arrive, from the periods spooled to a
temporary file: at most one batch of periods per added period, so the work per period is
bounded (about (1 + MIN_GROWTH) / MIN_GROWTH / BATCH_PERIODS batches) and the work of a
run of P periods is O(P). Units: V.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass

import numpy as np

from dsp.lpm_record import (
    WHOLE_RECORD_PERIODS,
    BatchedRecord,
    RecordEstimate,
    record_estimate,
)
from dsp.multisine import Plan

BATCH_PERIODS = 16  # the batch app.io.hdf5.iter_batches reads: the same rounding as analyze
MIN_GROWTH = 0.125  # a checkpoint is at least 12.5 % longer than the last (bounded work)
MAX_GROWTH = 1.0  # ... and at most twice it (a target met is seen within 2x its periods)


def next_checkpoint(
    count: int, worst_type_a: float, target: float | None, last: int | None = None
) -> int:
    """The record length (periods) at which to estimate next, after an estimate of `count`
    periods with worst relative type A `worst_type_a`: where that type A is expected to reach
    `target` (count (worst / target)^2; without a target, or a type A not finite, the longest
    step), within count (1 + MIN_GROWTH) .. count (1 + MAX_GROWTH), at most `last` (the
    run's last period, when known) and at least count + 1."""
    low = count + max(1, math.ceil(count * MIN_GROWTH))
    high = count + max(1, math.ceil(count * MAX_GROWTH))
    if target is not None and target > 0 and math.isfinite(worst_type_a) and worst_type_a > 0:
        predicted = math.ceil(count * (worst_type_a / target) ** 2 - 1e-9)
    else:
        predicted = high
    chosen = min(max(predicted, low), high)
    if last is not None:
        chosen = min(chosen, last)
    return max(chosen, count + 1)


class PeriodSpool:
    """Periods of `channels` channels of `period_samples` samples (float64, V), appended in
    order and read back by range from an unnamed temporary file (deleted when closed):
    memory independent of their number."""

    def __init__(self, period_samples: int, channels: int, directory: str | None = None):
        self.period_samples, self.channels = int(period_samples), int(channels)
        self.count = 0
        self._file = tempfile.TemporaryFile(dir=directory)  # closed by close()

    def append(self, *channels: np.ndarray) -> None:
        """One period of every channel (each N samples, V)."""
        block = np.stack([np.asarray(x, dtype=np.float64).reshape(-1) for x in channels])
        if block.shape != (self.channels, self.period_samples):
            raise ValueError(
                f"spool: {self.channels} channels of {self.period_samples} samples, got "
                f"{block.shape}"
            )
        self._file.seek(0, 2)
        self._file.write(block.tobytes())
        self.count += 1

    def read(self, first: int, stop: int) -> list[np.ndarray]:
        """Periods `first` .. `stop` - 1 per channel, each a C-contiguous (periods, N) array."""
        if not 0 <= first < stop <= self.count:
            raise ValueError(f"spool: periods {first}..{stop - 1} of {self.count}")
        size = self.channels * self.period_samples
        self._file.seek(first * size * 8)
        data = np.frombuffer(self._file.read((stop - first) * size * 8), dtype=np.float64)
        data = data.reshape(stop - first, self.channels, self.period_samples)
        return [np.ascontiguousarray(data[:, c, :]) for c in range(self.channels)]

    def close(self) -> None:
        self._file.close()


@dataclass
class _Pending:
    """The batched record of the next checkpoint, being fed from the spool."""

    periods: int  # the checkpoint: the record's length
    scheduled_at: int  # the record's length when it was scheduled
    record: BatchedRecord
    fed: int = 0  # periods fed so far (whole batches, then the tail)


class LiveRecord:
    """A live LPM run's record, period by period (`add`): `due` says whether the record so
    far is estimated now (every period up to WHOLE_RECORD_PERIODS, then at checkpoints),
    `estimate` gives it (any time: off a checkpoint the spooled record is read once in
    batches), `measured` tells it the worst type A of an estimate to choose the next
    checkpoint. `target`: the run's relative type A target or None; `last`: the run's last
    period when known (its period count, or the time bound's). Close it (`close`, or `with`)."""

    def __init__(
        self,
        plan: Plan,
        *,
        target: float | None = None,
        last: int | None = None,
        directory: str | None = None,
    ):
        self.plan, self.target, self.last = plan, target, last
        self.count = 0
        self.batch_periods_fed = 0  # periods added to batched records in all (the work)
        self._blocks: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._spool = PeriodSpool(plan.period_samples, 3, directory)
        self._sums: list[np.ndarray] = []
        self._pending: _Pending | None = None

    def __enter__(self) -> LiveRecord:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._spool.close()
        self._pending = None
        self._blocks = []

    @property
    def checkpoint(self) -> int | None:
        """The record length of the next batched estimate (None: every period, or not chosen)."""
        return None if self._pending is None else self._pending.periods

    @property
    def due(self) -> bool:
        """Whether the record so far is estimated now."""
        return self.count <= WHOLE_RECORD_PERIODS or self.checkpoint == self.count

    def add(
        self,
        reference: np.ndarray,
        dut: np.ndarray,
        played: np.ndarray,
        recorded_drive: np.ndarray | None = None,
    ) -> None:
        """One period (N samples each, V): the channels, the drive as played (the whole
        record's drive check, as before) and as recorded (the batched record's, as `analyze`
        reads it; None: as played)."""
        drive = played if recorded_drive is None else recorded_drive
        self._spool.append(reference, dut, drive)
        self.count += 1
        if self.count <= WHOLE_RECORD_PERIODS:
            self._blocks.append((reference, dut, played))
        else:
            self._blocks = []  # the record is spooled: memory independent of its length
            for i, x in enumerate((reference, dut)):
                self._sums[i] += x
            self._feed()
        if self.count == WHOLE_RECORD_PERIODS:
            self._sums = [np.sum([b[i] for b in self._blocks], axis=0) for i in (0, 1)]

    def measured(self, worst_type_a: float) -> None:
        """The worst relative type A of the estimate of the record so far: from
        WHOLE_RECORD_PERIODS on, the next checkpoint is chosen (`next_checkpoint`)."""
        if self.count < WHOLE_RECORD_PERIODS or (self.last is not None and self.count >= self.last):
            return
        periods = next_checkpoint(self.count, worst_type_a, self.target, self.last)
        self._pending = _Pending(periods, self.count, BatchedRecord(periods, self.plan))
        self._feed()

    def _feed(self) -> None:
        """Feed the pending record whole batches of the spool at a steady pace, so that they
        are all in by its checkpoint: at most about one batch per added period."""
        pending = self._pending
        if pending is None or pending.periods < self.count:
            return
        whole = pending.periods // BATCH_PERIODS
        span = pending.periods - pending.scheduled_at
        due = math.ceil(whole * (self.count - pending.scheduled_at) / span) if span else whole
        while pending.fed // BATCH_PERIODS < due and pending.fed + BATCH_PERIODS <= self.count:
            self._feed_periods(pending, pending.fed + BATCH_PERIODS)

    def _feed_periods(self, pending: _Pending, stop: int) -> None:
        reference, dut, drive = self._spool.read(pending.fed, stop)
        pending.record.add(reference, dut, drive)
        self.batch_periods_fed += stop - pending.fed
        pending.fed = stop

    def estimate(self) -> RecordEstimate:
        """The LPM estimate of the record so far: whole up to WHOLE_RECORD_PERIODS (the
        drive as played), else batched (the drive as recorded); at a checkpoint from the
        record fed meanwhile, off one the spool is read once in batches."""
        if self.count <= WHOLE_RECORD_PERIODS:
            ref = np.array([b[0] for b in self._blocks])
            dut = np.array([b[1] for b in self._blocks])
            drive = np.array([b[2] for b in self._blocks])
            return record_estimate(ref, dut, self.plan, drive_blocks=drive)
        pending, self._pending = self._pending, None
        if pending is None or pending.periods != self.count:
            pending = None  # (its accumulator freed before another is made)
            pending = _Pending(self.count, self.count, BatchedRecord(self.count, self.plan))
        while pending.fed < self.count:
            self._feed_periods(pending, min(pending.fed + BATCH_PERIODS, self.count))
        return pending.record.estimate()

    def mean_periods(self) -> tuple[np.ndarray, np.ndarray]:
        """The record's mean period of reference and DUT (V), each shape (N,)."""
        if self.count <= WHOLE_RECORD_PERIODS:
            return (
                np.mean([b[0] for b in self._blocks], axis=0),
                np.mean([b[1] for b in self._blocks], axis=0),
            )
        return self._sums[0] / self.count, self._sums[1] / self.count
