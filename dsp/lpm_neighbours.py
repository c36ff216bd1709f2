"""The record's DFT near its period grid, built a batch of periods at a time (issue 34 point 4):
`NeighbourAccumulator` adds periods exactly into a `NeighbourSpectrum`, which holds only the
bins within a half-width of a period-grid bin, in memory independent of the record's length.
Spectra in V (peak-scaled), bins are record bins (k = P m + c). numpy only."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from dsp.lpm import LpmError


class NeighbourSpectrum:
    """The peak-scaled spectrum ((2/(P N)) rfft, V) of a real record of P periods of N samples,
    held only at the record bins within `half_width` bins of a period-grid bin (k = P m + c
    with c or P - c at most `half_width`): every bin the LPM's windows, the lines and their
    harmonics' neighbourhoods need, in memory (half_width + 1) N values whatever P. Index it
    with record bins (an int or an int array) like the full spectrum; a bin it does not hold is
    an LpmError naming it. `table` row i holds the bins P m + classes[i], m = 0..N-1 (beyond
    Nyquist too); a class P - c not stored is read from class c, X[k] = conj(X[P N - k]).
    Built by `NeighbourAccumulator`."""

    def __init__(
        self,
        periods: int,
        period_samples: int,
        half_width: int,
        classes: np.ndarray,
        table: np.ndarray,
    ):
        self.periods = int(periods)
        self.period_samples = int(period_samples)
        self.half_width = int(half_width)
        self.classes = np.asarray(classes, dtype=np.int64)
        self.table = table
        self._row = np.full(self.periods, -1, dtype=np.int64)
        self._row[self.classes] = np.arange(self.classes.size)

    @property
    def size(self) -> int:
        """rfft bins of the whole record (P N / 2 + 1)."""
        return self.periods * self.period_samples // 2 + 1

    def _where(self, bins: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per bin: table row, column, and whether the value is stored conjugated."""
        k = np.asarray(bins, dtype=np.int64)
        p, n = self.periods, self.period_samples
        c = k % p
        direct = self._row[c]
        mirrored = self._row[(p - c) % p]
        conj = (direct < 0) & (mirrored >= 0)
        rows = np.where(conj, mirrored, direct)
        cols = np.where(conj, n - 1 - k // p, k // p)
        bad = (rows < 0) | (k < 0) | (k >= self.size)
        if np.any(bad):
            raise LpmError(
                f"bin {int(np.atleast_1d(k)[np.atleast_1d(bad)][0])}: not held (further than "
                f"{self.half_width} bins from the period grid, or beyond Nyquist)"
            )
        return rows, cols, conj

    def __getitem__(self, bins: Any) -> Any:
        rows, cols, conj = self._where(bins)
        values = self.table[rows, cols]
        return np.where(conj, np.conj(values), values)

    def __setitem__(self, bins: Any, values: Any) -> None:
        rows, cols, conj = self._where(bins)
        v = np.broadcast_to(np.asarray(values, dtype=complex), np.shape(rows))
        self.table[rows, cols] = np.where(conj, np.conj(v), v)

    def held_bins(self) -> np.ndarray:
        """Every record bin held up to Nyquist, ascending."""
        c = np.arange(self.periods)
        held = c[np.minimum(c, self.periods - c) <= self.half_width]
        out = (self.periods * np.arange(self.period_samples)[None, :] + held[:, None]).ravel()
        return np.sort(out[out < self.size])

    def copy(self) -> NeighbourSpectrum:
        return NeighbourSpectrum(
            self.periods, self.period_samples, self.half_width, self.classes, self.table.copy()
        )

    def __truediv__(self, factor: float) -> NeighbourSpectrum:
        return NeighbourSpectrum(
            self.periods, self.period_samples, self.half_width, self.classes, self.table / factor
        )


class NeighbourAccumulator:
    """The DFT near the period grid of `channels` real records of one length, accumulated a
    batch of periods at a time, exactly: for record bin k = P m + c,
        X[k] = sum_p exp(-j 2 pi c p / P) FFT_N(x_p exp(-j 2 pi c n / (P N)))[m],
    one N-point FFT per residue class c = 0..half_width per period and channel (x_p the p-th
    period; the classes P - c follow by conjugate symmetry). The first period is taken from
    every period and its DFT added back to the class 0 (the sum of the phases is P there and 0
    for every other class), so the steady part does not cancel in rounding. `periods` P is the
    record's length, known in advance; periods are added in order. Memory: the classes'
    tables, independent of P."""

    def __init__(self, periods: int, period_samples: int, half_width: int, channels: int) -> None:
        if periods < 1 or period_samples < 2 or half_width < 0 or channels < 1:
            raise LpmError(
                "neighbourhood: periods >= 1, period samples >= 2, half width >= 0, channels >= 1"
            )
        self.periods, self.period_samples = int(periods), int(period_samples)
        self.half_width = int(half_width)
        self.classes = np.arange(min(half_width, periods - 1) + 1)
        n = np.arange(period_samples)
        self._modulation = np.exp(
            -2j * np.pi * np.outer(self.classes, n) / (periods * period_samples)
        )
        self._tables = np.zeros((channels, self.classes.size, period_samples), complex)
        self._handed: set[int] = set()
        self._first: list[np.ndarray] | None = None
        self.added = 0

    def add(self, *channels: np.ndarray | Callable[[], np.ndarray]) -> None:
        """Add the same consecutive periods of every channel, each shape (periods, N), V. A
        channel may be given as a function that makes it (e.g. a power of another): it is
        made when its turn comes, so one such channel is in memory at a time."""
        made = [x for x in channels if not callable(x)]
        blocks = [np.atleast_2d(np.asarray(x, dtype=float)) for x in made]
        count = blocks[0].shape[0] if blocks else 0
        if (
            len(channels) != self._tables.shape[0]
            or not blocks
            or any(x.shape != (count, self.period_samples) for x in blocks)
            or self.added + count > self.periods
            or self._handed
        ):
            raise LpmError(
                f"neighbourhood: {self._tables.shape[0]} channels of periods of "
                f"{self.period_samples} samples, at most {self.periods} in all; got "
                f"{[x.shape for x in blocks]} after {self.added}"
            )
        keep_first = self._first is None
        if keep_first:
            self._first = []
        assert self._first is not None
        p = np.arange(self.added, self.added + count)
        # each period less the first: the steady part, common to all, would otherwise add
        # P terms of the lines' size that cancel to the noise (rounding 10x the record's DFT)
        phases = np.exp(-2j * np.pi * np.outer(self.classes, p) / self.periods)
        given = iter(blocks)
        for c, (table, channel) in enumerate(zip(self._tables, channels, strict=True)):
            x = (
                np.atleast_2d(np.asarray(channel(), dtype=float))
                if callable(channel)
                else next(given)
            )
            if x.shape != (count, self.period_samples):
                raise LpmError(
                    f"neighbourhood: channel {c} made {x.shape}, not {(count, self.period_samples)}"
                )
            if keep_first:
                self._first.append(x[0].copy())
            rest = x - self._first[c]
            del x
            for i in range(self.classes.size):
                # the phase sum as a plain product and sum over the periods, not a BLAS gemv:
                # a threaded BLAS on a busy machine spun 12x the FFTs' time on it (load 8)
                spectra = np.fft.fft(rest * self._modulation[i], axis=1)
                table[i] += (phases[i][:, None] * spectra).sum(axis=0)
        self.added += count

    def spectrum(self, channel: int = 0) -> NeighbourSpectrum:
        """A channel's held bins, peak-scaled (2 / (P N)); every period must have been added.
        The accumulator's table is scaled in place and handed over (no copy)."""
        if self.added != self.periods:
            raise LpmError(f"neighbourhood: {self.added} of {self.periods} periods added")
        table = self._tables[channel]
        if channel not in self._handed:
            assert self._first is not None
            # the first period, taken from every period, added back: sum_p exp(-j 2 pi c p/P)
            # is P for the class c = 0 and exactly 0 for the others
            table[0] += self.periods * np.fft.fft(self._first[channel])
            table *= 2.0 / (self.periods * self.period_samples)
            self._handed.add(channel)
        return NeighbourSpectrum(
            self.periods, self.period_samples, self.half_width, self.classes, table
        )
