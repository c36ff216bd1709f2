"""Excitation time to a type A target: multisine against stepped sine (SPEC.md s.12).

Both on the same simulated stand (nominal values, same seed), same estimator and target at
every line, each with the settings that give it its best: the multisine with its default
procedure (identification, closed-loop equalisation, acquisition until the target); the stepped
sine with short blocks (a whole number of cycles of the line and of the mains, >= 0.25 s), a
level loop started from the previous line's response, three-parameter sine fits. The figure
is the time the shaker ran (fades included, background excluded).

Three regimes: the seed's piezo at its seed level, where the target does not bind (type A is
far below it after the minimum three periods: the figure compares the procedures' fixed
overheads); the seed's capacitive DUT, whose 1/f^2 response leaves only the top lines
noise-limited; and the piezo at a low level, where every line is noise-limited and the
target binds everywhere.

Run: python bench/excitation_time.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.procedure import Procedure, RunSettings
from app.stand_config import load
from app.stands import open_stand
from dsp.multisine import preset_plan

# (DUT and preset, level in m/s^2 per line (None: the preset's), type A target)
CASES = (
    ("piezo", None, 0.002),
    ("capacitive", None, 0.01),
    ("piezo", 0.05, 0.001),
    ("piezo", 0.05, 0.0005),
    ("piezo", 0.05, 0.0002),
)


def one(
    dut: str, level: float | None, target: float, mode: str
) -> tuple[float, float, bool, float]:
    stand = open_stand(load(), dut=dut, seed=5, systematic=False)
    settings = RunSettings(mode=mode, target_type_a=target, max_acquisition_s=40000.0)
    t0 = time.perf_counter()
    finished = Procedure(stand, preset_plan(dut, level_ms2=level), settings).run()
    wall = time.perf_counter() - t0
    stand.close()
    worst = max(ln.relative_type_a for ln in finished.results.lines)
    return finished.record.excitation_time_s, worst, worst <= target, wall


def main() -> None:
    print("| DUT | level per line | type A target, every line | multisine | stepped sine | ratio |")
    print("| --- | --- | --- | --- | --- | --- |")
    for dut, level, target in CASES:
        multi = one(dut, level, target, "multisine")
        stepped = one(dut, level, target, "stepped-sine")

        def cell(r: tuple[float, float, bool, float]) -> str:
            reached = "" if r[2] else f" (not reached: worst {100 * r[1]:.2f} %)"
            return f"{r[0]:.0f} s{reached}"

        print(
            f"| {dut} | {preset_plan(dut, level_ms2=level).amplitudes_ms2[0]:g} m/s^2 "
            f"| {100 * target:g} % | {cell(multi)} | {cell(stepped)} | "
            f"{stepped[0] / multi[0]:.1f}{'' if stepped[2] else ' (lower bound)'} |"
        )


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
