"""Coverage of the k = 2 interval over many simulated runs with known truth (SPEC.md s.12).

Each run: the simulated stand draws its own systematic deviations from its budget (reference
certificate, gains, mounting) and its noise from the seed; the analysis sees only the
certificate and nominal values. Target: the interval covers the truth 93-97.5 % of the time at
every line.

Run: python bench/coverage.py [RUNS] [DUT]   (default 600 runs, piezo; two processes)
     python bench/coverage.py --smoke        (2 runs: checks it still runs)
"""

from __future__ import annotations

import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.io.hdf5 import read_recording
from app.procedure.analysis import analyze
from app.procedure.simulate import simulate


def one_run(args: tuple[int, str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    seed, dut = args
    with tempfile.TemporaryDirectory() as tmp:
        run = simulate(Path(tmp) / "r.h5", dut=dut, level_ms2=5.0, periods=4, seed=seed, settle=2)
        recording = read_recording(run.path)
    results = analyze(recording).results
    truth = recording.truth
    s = np.array([ln.sensitivity_mv_per_ms2 for ln in results.lines])
    u = np.array([ln.expanded_uncertainty_mv_per_ms2 for ln in results.lines])
    phase = np.array([ln.phase_deg for ln in results.lines])
    u_phase = np.array([ln.phase_expanded_uncertainty_deg for ln in results.lines])
    phase_error = (phase - truth.phase_deg + 180) % 360 - 180
    return (
        np.abs(s - truth.sensitivity_mv_per_ms2) <= u,
        np.abs(phase_error) <= u_phase,
        np.array([ln.nominal_frequency_hz for ln in results.lines]),
    )


def wilson(p: float, n: int, z: float = 1.96) -> tuple[float, float]:
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


def main() -> None:
    args = [a for a in sys.argv[1:] if a != "--smoke"]
    runs = 2 if "--smoke" in sys.argv[1:] else int(args[0]) if args else 600
    dut = args[1] if len(args) > 1 else "piezo"
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=2) as pool:
        outcomes = list(pool.map(one_run, [(seed, dut) for seed in range(runs)], chunksize=8))
    elapsed = time.perf_counter() - t0
    magnitude = np.array([o[0] for o in outcomes])
    phase = np.array([o[1] for o in outcomes])
    freqs = outcomes[0][2]
    ref = int(np.flatnonzero(freqs == 160.0)[0])
    print(
        f"{runs} simulated {dut} runs (4 periods each, systematic deviations drawn per run) "
        f"in {elapsed:.0f} s"
    )
    print("| line | magnitude coverage | 95 % interval of the estimate | phase coverage |")
    print("| --- | --- | --- | --- |")
    for k, f in enumerate(freqs):
        lo, hi = wilson(magnitude[:, k].mean(), runs)
        mark = " (reference)" if k == ref else ""
        print(
            f"| {f:g} Hz{mark} | {100 * magnitude[:, k].mean():.1f} % | "
            f"{100 * lo:.1f}-{100 * hi:.1f} % | {100 * phase[:, k].mean():.1f} % |"
        )
    print(
        f"| all lines | min {100 * magnitude.mean(axis=0).min():.1f} %, "
        f"max {100 * magnitude.mean(axis=0).max():.1f} % | | min "
        f"{100 * phase.mean(axis=0).min():.1f} %, max {100 * phase.mean(axis=0).max():.1f} % |"
    )


if __name__ == "__main__":
    main()
