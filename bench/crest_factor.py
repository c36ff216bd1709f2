"""Crest factor of the seed multisine plans: random, Schroeder and optimised phases.

Run from the repository root:  python bench/crest_factor.py [--smoke]

For the piezo (fs 6000 Hz, 12000-sample period) and capacitive (fs 12000 Hz, 24000-sample
period) seed plans, with equal amplitudes and with amplitudes proportional to 1/f, prints a
markdown table: crest factor of 200 random phase draws (median and 10-90 % range), of
Schroeder's phases and of `optimise_phases`, the process CPU time of the optimisation, and
that time divided by a baseline measured in the same run (1000 `synthesize` calls of the
same plan), which makes the figure comparable between machines.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dsp.crestfactor import (
    crest_factor,
    optimise_phases,
    random_phases,
    schroeder_phases,
    synthesize,
)

ISO266_10_2500 = [10, 12.5, 16, 20, 25, 31.5, 40, 50, 63, 80, 100, 125, 160, 200, 250, 315]
ISO266_10_2500 += [400, 500, 630, 800, 1000, 1250, 1600, 2000, 2500]

PLANS = {  # name: (sample rate in Hz, period in samples, nominal line frequencies in Hz)
    "piezo": (6000.0, 12000, ISO266_10_2500),
    "capacitive": (12000.0, 24000, [*ISO266_10_2500, 3150, 4000]),
}
SMOKE = "--smoke" in sys.argv[1:]  # one plan, few draws: checks it still runs
RANDOM_DRAWS = 5 if SMOKE else 200
BASELINE_CALLS = 10 if SMOKE else 1000


def bench(fs: float, n: int, freqs: list[float], amplitudes: np.ndarray) -> dict[str, float]:
    bins = np.rint(np.asarray(freqs) * n / fs).astype(int)
    rng = np.random.default_rng(12345)
    draws = [
        crest_factor(synthesize(bins, amplitudes, random_phases(bins.size, rng), n))
        for _ in range(RANDOM_DRAWS)
    ]
    schroeder = crest_factor(synthesize(bins, amplitudes, schroeder_phases(amplitudes), n))

    zeros = np.zeros(bins.size)
    t0 = time.process_time()
    for _ in range(BASELINE_CALLS):
        synthesize(bins, amplitudes, zeros, n)
    baseline_s = time.process_time() - t0

    t0 = time.process_time()
    phases = optimise_phases(bins, amplitudes, n, seed=0)
    optimise_s = time.process_time() - t0
    return {
        "lines": bins.size,
        "random_median": float(np.median(draws)),
        "random_p10": float(np.percentile(draws, 10)),
        "random_p90": float(np.percentile(draws, 90)),
        "schroeder": schroeder,
        "optimised": crest_factor(synthesize(bins, amplitudes, phases, n)),
        "optimise_s": optimise_s,
        "baseline_s": baseline_s,
    }


def main() -> None:
    print(f"numpy {np.__version__}; CPU times are time.process_time() of this process\n")
    header = (
        "| plan | amplitudes | lines | random median (10-90 %) | Schroeder | optimised "
        f"| optimise CPU s | {BASELINE_CALLS} x synthesize CPU s | ratio |"
    )
    print(header)
    print("|---" * (header.count("|") - 1) + "|")
    for name, (fs, n, freqs) in list(PLANS.items())[: 1 if SMOKE else None]:
        f = np.asarray(freqs, dtype=float)
        for label, amplitudes in (("equal", np.ones(f.size)), ("1/f", f[0] / f)):
            r = bench(fs, n, freqs, amplitudes)
            print(
                f"| {name} | {label} | {r['lines']} "
                f"| {r['random_median']:.2f} ({r['random_p10']:.2f}-{r['random_p90']:.2f}) "
                f"| {r['schroeder']:.2f} | {r['optimised']:.3f} | {r['optimise_s']:.2f} "
                f"| {r['baseline_s']:.2f} | {r['optimise_s'] / r['baseline_s']:.1f} |"
            )


if __name__ == "__main__":
    main()
