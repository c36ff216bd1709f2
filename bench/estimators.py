"""Estimator bias and efficiency against the Cramer-Rao bound (SPEC.md s.12).

White noise on both channels, 20 dB SNR per line per period, L periods. Cramer-Rao bound for
the relative magnitude: var(|H|)/|H|^2 >= 2 s_y^2/(N A_y^2) + 2 s_u^2/(N A_u^2), N the total
samples. Target for `periodic`: Monte Carlo std within 10 % of the bound, bias < 0.05 %.

Run: python bench/estimators.py [--smoke]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dsp.spectral import ESTIMATORS, RECORD_ESTIMATORS, SpectralAccumulator

N_P = 1200  # period, samples
BINS = np.array([20, 50, 130, 320])
PERIODS = 16
RUNS = 20 if "--smoke" in sys.argv[1:] else 4000  # --smoke: checks it still runs
SNR_DB = 20.0
# the estimators the accumulator streams; a record estimator (lpm) analyses one whole record
# (dsp.lpm_record) and is benched on its own (bench/lpm_coverage.py)
STREAMED = tuple(name for name in ESTIMATORS if name not in RECORD_ESTIMATORS)


def main() -> None:
    rng = np.random.default_rng(1)
    i = np.arange(N_P)
    truth = 0.035 * np.exp(-0.6j)
    u0 = sum(np.sin(2 * np.pi * m * i / N_P + 0.7 * k) for k, m in enumerate(BINS))
    y0 = sum(
        abs(truth) * np.sin(2 * np.pi * m * i / N_P + 0.7 * k + np.angle(truth))
        for k, m in enumerate(BINS)
    )
    # per-period line SNR A^2 / (4 s^2 / N_p) = 10^(SNR/10)
    s_u = np.sqrt(N_P / 4) * 10 ** (-SNR_DB / 20)
    s_y = s_u * abs(truth)
    n_total = N_P * PERIODS
    crb = np.sqrt(2 * s_y**2 / (n_total * abs(truth) ** 2) + 2 * s_u**2 / n_total)
    errors: dict[str, list[np.ndarray]] = {name: [] for name in STREAMED}
    t0 = time.perf_counter()
    for _ in range(RUNS):
        acc = SpectralAccumulator(N_P, BINS, track_floor=False)
        acc.add_periods(
            u0 + s_u * rng.standard_normal((PERIODS, N_P)),
            y0 + s_y * rng.standard_normal((PERIODS, N_P)),
        )
        for name in STREAMED:
            errors[name].append(np.abs(acc.estimate(name).response) / abs(truth) - 1)
    elapsed = time.perf_counter() - t0
    print(
        f"{RUNS} runs x {PERIODS} periods of {N_P} samples, {SNR_DB:g} dB per line per period "
        f"on both channels, {BINS.size} lines pooled ({elapsed:.0f} s)"
    )
    print(f"Cramer-Rao bound on the relative std of |H|: {100 * crb:.3f} %")
    print("| estimator | bias | std | std / bound |")
    print("| --- | --- | --- | --- |")
    for name, values in errors.items():
        e = np.array(values).ravel()
        print(
            f"| {name} | {100 * e.mean():+.3f} % (+-{100 * e.std() / np.sqrt(e.size):.3f}) | "
            f"{100 * e.std():.3f} % | {e.std() / crb:.3f} |"
        )


if __name__ == "__main__":
    main()
