"""Simulated stand speed: simulated seconds per wall second (target >= 50x at 51.2 kS/s).

The baseline measured in the same run is scipy.signal.sosfilt of the same number of samples
through one 10th-order filter per channel, so the ratio shows the cost of the physics
relative to the cheapest possible per-sample work.

Run: python bench/sim_speed.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import scipy.signal

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hardware.interfaces import DaqConfig, InputChannel, OutputChannel
from sim.stand import SimulatedStand

PERIODS = 20


def simulate(dut: str, fs: float) -> float:
    n = int(2 * fs)
    stand = SimulatedStand(dut, seed=1)
    stand.configure(
        DaqConfig(
            fs,
            n,
            OutputChannel("ao0", 10.0),
            (
                InputChannel("reference", "ai0", 1.0),
                InputChannel("dut", "ai1", 5.0),
                InputChannel("drive", "ai2", 10.0),
            ),
        )
    )
    stand.start(0.05 * np.random.default_rng(0).standard_normal(n))
    t0 = time.perf_counter()
    for _ in range(PERIODS):
        stand.read_period()
    return time.perf_counter() - t0


def baseline(fs: float) -> float:
    n = int(2 * fs) * PERIODS
    sos = scipy.signal.butter(10, 0.3, output="sos")
    x = np.random.default_rng(0).standard_normal(n)
    t0 = time.perf_counter()
    for _ in range(2):
        scipy.signal.sosfilt(sos, x)
    return time.perf_counter() - t0


def main() -> None:
    print("| DUT | fs | simulated | wall | real-time factor | ratio to sosfilt baseline |")
    print("| --- | --- | --- | --- | --- | --- |")
    for dut, fs in (("piezo", 6000.0), ("capacitive", 12000.0), ("capacitive", 51200.0)):
        wall = min(simulate(dut, fs) for _ in range(3))
        base = min(baseline(fs) for _ in range(3))
        simulated = 2 * PERIODS
        print(
            f"| {dut} | {fs / 1000:g} kS/s | {simulated} s | {wall:.2f} s | "
            f"{simulated / wall:.0f}x | {wall / base:.1f} |"
        )


if __name__ == "__main__":
    main()
