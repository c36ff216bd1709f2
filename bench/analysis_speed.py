"""Analysis speed and memory against scipy's csd/welch on the same record (SPEC.md s.12).

Record: 60 s, 2 channels at 51.2 kS/s, 2 s periods (N = 102400), ISO 266 lines 10 Hz-20 kHz,
white noise on both channels. Baseline: scipy.signal.csd + welch of both channels (what H1 and
coherence need), rectangular window, nperseg = N, no overlap, no detrend. Ours: the streaming
SpectralAccumulator fed in 16-period batches, then every streamed estimator (not the record
estimators such as lpm, which analyse one whole record: bench/lpm_coverage.py). Figures are
ratios to the baseline measured in the same run, so a noisy machine does not move them much.

Run: python bench/analysis_speed.py [--smoke]   (--smoke: a 4 s record, one repeat)
"""

from __future__ import annotations

import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import scipy.signal

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dsp import iso266
from dsp.crestfactor import schroeder_phases, synthesize
from dsp.spectral import ESTIMATORS, RECORD_ESTIMATORS, SpectralAccumulator

FS = 51_200.0
N = 102_400
SMOKE = "--smoke" in sys.argv[1:]  # a few seconds, figures meaningless: keeps it running
RECORD_S = 4.0 if SMOKE else 60.0
PERIODS = int(RECORD_S * FS / N)
# the estimators the accumulator streams; a record estimator (lpm) analyses the whole record at
# once (dsp.lpm_record) and has its own bench (bench/lpm_coverage.py)
STREAMED = tuple(name for name in ESTIMATORS if name not in RECORD_ESTIMATORS)


def make_record(periods: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    freqs = np.array(iso266.nominal_frequencies(10, 20_000))
    bins = np.round(freqs * N / FS).astype(int)
    amps = np.ones(bins.size)
    period = synthesize(bins, amps, schroeder_phases(amps), N)
    rng = np.random.default_rng(seed)
    u = np.tile(period, periods) + 1e-3 * rng.standard_normal(periods * N)
    y = 0.01 * np.tile(period, periods) + 1e-4 * rng.standard_normal(periods * N)
    return bins, u, y


def ours(bins: np.ndarray, u: np.ndarray, y: np.ndarray) -> None:
    acc = SpectralAccumulator(N, bins)
    uu, yy = u.reshape(-1, N), y.reshape(-1, N)
    for start in range(0, uu.shape[0], 16):
        acc.add_periods(uu[start : start + 16], yy[start : start + 16])
    for name in STREAMED:
        acc.estimate(name)


def baseline(bins: np.ndarray, u: np.ndarray, y: np.ndarray) -> None:
    kw = dict(fs=FS, window="boxcar", nperseg=N, noverlap=0, detrend=False)
    _, p_uy = scipy.signal.csd(u, y, **kw)
    _, p_uu = scipy.signal.welch(u, **kw)
    _, p_yy = scipy.signal.welch(y, **kw)
    _ = p_uy[bins] / p_uu[bins], np.abs(p_uy[bins]) ** 2 / (p_uu[bins] * p_yy[bins])


def best_of(fn, *args, repeats: int = 1 if SMOKE else 5) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(*args)
        times.append(time.perf_counter() - t0)
    return min(times)


def peak_memory(fn, *args) -> float:
    tracemalloc.start()
    fn(*args)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak / 2**20


def streamed_peak(periods: int) -> float:
    """Peak memory (MiB) of the live path: one period generated, added and estimated at a time."""
    freqs = np.array(iso266.nominal_frequencies(10, 20_000))
    bins = np.round(freqs * N / FS).astype(int)
    period = synthesize(bins, np.ones(bins.size), schroeder_phases(np.ones(bins.size)), N)
    rng = np.random.default_rng(1)
    tracemalloc.start()
    acc = SpectralAccumulator(N, bins)
    for _ in range(periods):
        acc.add_period(period + 1e-3 * rng.standard_normal(N), 0.01 * period)
        acc.estimate()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak / 2**20


def per_period_time(bins: np.ndarray, u: np.ndarray, y: np.ndarray) -> float:
    """Seconds to add one period and update the live estimate (the GUI's per-period work)."""
    acc = SpectralAccumulator(N, bins)
    uu, yy = u.reshape(-1, N), y.reshape(-1, N)
    t0 = time.perf_counter()
    for k in range(uu.shape[0]):
        acc.add_period(uu[k], yy[k])
        acc.estimate()
    return (time.perf_counter() - t0) / uu.shape[0]


def main() -> None:
    bins, u, y = make_record(PERIODS)
    data_mib = (u.nbytes + y.nbytes) / 2**20
    t_base = best_of(baseline, bins, u, y)
    t_ours = best_of(ours, bins, u, y)
    m_base = peak_memory(baseline, bins, u, y)
    m_ours = peak_memory(ours, bins, u, y)
    live = per_period_time(bins, u, y)
    short, long = (
        (streamed_peak(2), streamed_peak(4)) if SMOKE else (streamed_peak(10), streamed_peak(100))
    )
    print(
        f"record: {RECORD_S:g} s, 2 x {FS:g} S/s, {PERIODS} periods of {N} samples, "
        f"{bins.size} lines, {data_mib:.0f} MiB of samples; estimators {', '.join(STREAMED)}"
    )
    print("| figure | scipy csd+welch (baseline) | accelcal | ratio |")
    print("| --- | --- | --- | --- |")
    print(f"| analysis time, best of 5 | {t_base:.3f} s | {t_ours:.3f} s | {t_ours / t_base:.2f} |")
    print(
        f"| peak extra memory (tracemalloc) | {m_base:.0f} MiB | {m_ours:.0f} MiB | "
        f"{m_ours / m_base:.2f} |"
    )
    print(
        f"| real-time margin (record / analysis time) | {RECORD_S / t_base:.0f}x | "
        f"{RECORD_S / t_ours:.0f}x | |"
    )
    print(
        f"| live: add one 2 s period + estimate | | {1e3 * live:.1f} ms | "
        f"margin {N / FS / live:.0f}x |"
    )
    print(
        f"| live path peak memory, 10 vs 100 periods | | {short:.1f} / {long:.1f} MiB | "
        f"{long / short:.2f} |"
    )


if __name__ == "__main__":
    main()
