"""Simulated stand speed: simulated seconds per wall second (target >= 50x at 51.2 kS/s).

The baseline measured in the same run is scipy.signal.sosfilt of the same number of samples
through one 10th-order filter per channel, so the ratio shows the cost of the physics
relative to the cheapest possible per-sample work. Each figure is the best of 3 in a fresh
interpreter; the CPU-time factor (process time) is printed beside the wall-time one because
other work on a shared machine stretches wall time only. `--also PATH` times the stand of
another checkout (e.g. an export of an older commit) in the same run, for a before/after
figure.

Run: python bench/sim_speed.py [--also /path/to/other/checkout] [--one-blas-thread] [--smoke]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PERIODS = 20  # of 2 s: 40 s simulated
CASES = (("piezo", 6000.0), ("capacitive", 12000.0), ("capacitive", 51200.0))

# Run in a fresh interpreter with the checkout to time first on sys.path: prints
# {"wall": s, "cpu": s} for the stand, or for the baseline when the DUT is "baseline".
_TIMER = """
import json, sys, time
import numpy as np
dut, fs, periods = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
n = int(2 * fs)
if dut == "baseline":
    import scipy.signal
    sos = scipy.signal.butter(10, 0.3, output="sos")
    x = np.random.default_rng(0).standard_normal(n * periods)
    def work():
        for _ in range(2):
            scipy.signal.sosfilt(sos, x)
else:
    from hardware.interfaces import DaqConfig, InputChannel, OutputChannel
    from sim.stand import SimulatedStand
    stand = SimulatedStand(dut, seed=1)
    stand.configure(DaqConfig(fs, n, OutputChannel("ao0", 10.0), (
        InputChannel("reference", "ai0", 1.0), InputChannel("dut", "ai1", 5.0),
        InputChannel("drive", "ai2", 10.0))))
    stand.start(0.05 * np.random.default_rng(0).standard_normal(n))
    def work():
        for _ in range(periods):
            stand.read_period()
walls, cpus = [], []
for _ in range(3):
    w, c = time.perf_counter(), time.process_time()
    work()
    walls.append(time.perf_counter() - w)
    cpus.append(time.process_time() - c)
print(json.dumps({"wall": min(walls), "cpu": min(cpus)}))
"""


def timed(root: Path, dut: str, fs: float, one_blas_thread: bool = False) -> dict[str, float]:
    """Best-of-3 wall and CPU seconds of PERIODS periods of the stand of checkout `root`."""
    env = dict(os.environ, PYTHONPATH=str(root))
    if one_blas_thread:
        env["OPENBLAS_NUM_THREADS"] = "1"
    out = subprocess.run(
        [sys.executable, "-c", _TIMER, dut, str(fs), str(PERIODS)],
        cwd=root,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--also", type=Path, action="append", default=[], help="other checkout")
    parser.add_argument(
        "--one-blas-thread", action="store_true", help="OPENBLAS_NUM_THREADS=1 in every timing"
    )
    parser.add_argument("--smoke", action="store_true", help="one case, one period: runs?")
    args = parser.parse_args()
    one = args.one_blas_thread
    global PERIODS, CASES
    if args.smoke:
        PERIODS, CASES = 1, CASES[:1]
    simulated = 2 * PERIODS
    head = "| DUT | fs | simulated | wall | real-time factor (wall) | (CPU) | ratio to sosfilt |"
    rule = "| --- | --- | --- | --- | --- | --- | --- |"
    for other in args.also:
        head += f" {other.name}: real-time factor (CPU) | speed-up (CPU) |"
        rule += " --- | --- |"
    print(head)
    print(rule)
    for dut, fs in CASES:
        ours = timed(ROOT, dut, fs, one)
        base = timed(ROOT, "baseline", fs, one)
        row = (
            f"| {dut} | {fs / 1000:g} kS/s | {simulated} s | {ours['wall']:.2f} s | "
            f"{simulated / ours['wall']:.0f}x | {simulated / ours['cpu']:.0f}x | "
            f"{ours['cpu'] / base['cpu']:.1f} |"
        )
        for other in args.also:
            theirs = timed(other.resolve(), dut, fs, one)
            row += f" {simulated / theirs['cpu']:.0f}x | {theirs['cpu'] / ours['cpu']:.2f} |"
        print(row)


if __name__ == "__main__":
    main()
