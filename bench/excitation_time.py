"""Excitation time to a type A target: multisine against stepped sine (SPEC.md s.12, issue 14).

Both modes on the same simulated stand (nominal values, seed 5), same estimator, the target at
every line, each with the settings that give it its best:
- multisine: equalisation from the stand's stored response (checked by its first settled
  step), the two settled periods reused as the first acquired ones, acquisition until the
  target (at least 3 periods), a fade-out of 4 cycles of the lowest line;
- stepped sine: blocks of whole cycles of the line and of the mains (at least 0.05, 0.1 or
  0.25 s: the best of the three is shown for each row), each line's
  level loop started from its own stored response, three-parameter sine fits, settled blocks
  reused, the same fade-out rule per line.
"Cold" is the first run of a stand, mass class and plan: no stored response, a gentle
identification first (the multisine's own figure; the stepped sine then extrapolates its
level loop from the last lines). The figure is the time the shaker ran: from the first to
the last non-zero drive sample of each burst (fades in, background and pauses out).

Tables:
1. the issue's example (piezo, 5 m/s^2 per line, 0.2 % type A) phase by phase, cold and warm,
   on the seed's 2 s plan and on a 1 s plan (12.5 and 31.5 Hz then sit at 12 and 32 Hz);
2. both modes, warm, at 0.2 %, 0.05 % and 0.02 % type A, at the seed level (the target binds
   nowhere: type A is ~0.002 % after 3 periods) and at 0.05 m/s^2 (every line ~60 dB above the
   noise: the target binds at every line), with how many lines the target binds at.

Run: python bench/excitation_time.py [--smoke]   (two minutes of CPU; --smoke: one run a table)
"""

from __future__ import annotations

import sys
import tempfile
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.io.vocabulary import Mode, RunStatus
from app.procedure import PeriodBlock, PeriodEstimate, Procedure, RunSettings
from app.stand.config import load
from app.stand.open import open_stand
from app.stand.response import ResponseStore
from dsp.multisine import PRESETS, Plan, make_plan, preset_plan
from dsp.spectral import MIN_PERIODS

CONFIG = load()
SMOKE = "--smoke" in sys.argv[1:]  # one run per table: checks it still runs
TARGETS = (0.002,) if SMOKE else (0.002, 0.0005, 0.0002)
LEVELS = (5.0,) if SMOKE else (5.0, 0.05)
STEPPED_BLOCKS_S = (
    (0.25,) if SMOKE else (0.05, 0.1, 0.25)
)  # the stepped sine's block: its best per row is shown


def plan_of(level: float, period_samples: int | None = None) -> Plan:
    """The seed's piezo plan at `level` m/s^2 per line, on its own or another period."""
    if period_samples is None:
        return preset_plan("piezo", level_ms2=level)
    preset = PRESETS["piezo"]
    return make_plan(
        preset.nominal_frequencies_hz,
        preset.sample_rate_hz,
        period_samples,
        level,
        preset.reference_frequency_hz,
    )


class Phases:
    """Excitation per state (s) from the PeriodBlock events, and the type A per line at the
    minimum number of periods (from the first PeriodEstimate)."""

    def __init__(self, sample_rate_hz: float):
        self.fs = sample_rate_hz
        self.seconds: dict[str, float] = defaultdict(float)
        self.first_type_a: np.ndarray | None = None

    def __call__(self, event: object) -> None:
        if isinstance(event, PeriodBlock):
            moving = np.flatnonzero(event.drive)
            if moving.size:
                self.seconds[str(event.state)] += (moving[-1] - moving[0] + 1) / self.fs
        elif isinstance(event, PeriodEstimate) and self.first_type_a is None:
            self.first_type_a = np.asarray(event.estimate.relative_type_a)


def one(
    store: ResponseStore, plan: Plan, target: float, mode: str, block_s: float = 0.25
) -> tuple[object, Phases]:
    """One run; its Finished event and its phases."""
    stand = open_stand(CONFIG, dut="piezo", seed=5, systematic=False)
    phases = Phases(plan.sample_rate_hz)
    settings = RunSettings(
        mode=mode,
        target_type_a=target,
        max_acquisition_s=40000.0,
        dut_mass_g=10.0,
        stepped_block_s=block_s,
    )
    try:
        finished = Procedure(stand, plan, settings, listener=phases, response_store=store).run()
    finally:
        stand.close()
    if finished.status != RunStatus.COMPLETE:
        raise SystemExit(f"{mode} at {target}: {finished.abort_reason}")
    return finished, phases


def table_phases(root: Path) -> None:
    print("Table 1: the issue's example, piezo at 5 m/s^2 per line, 0.2 % type A, multisine")
    print()
    print("| plan | run | identification | equalisation | acquisition | fade-out | total |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    plans = (("1 s", 6000),) if SMOKE else (("2 s (seed)", None), ("1 s", 6000))
    for label, period in plans:
        store = ResponseStore(root / f"phases-{period}")
        plan = plan_of(5.0, period)
        for run in ("cold",) if SMOKE else ("cold", "warm"):
            finished, p = one(store, plan, 0.002, Mode.MULTISINE)
            s = p.seconds
            print(
                f"| {label} | {run} | {s['identifying']:.1f} s | {s['equalising']:.1f} s | "
                f"{s['acquiring']:.1f} s | {s['fading out']:.2f} s | "
                f"**{finished.record.excitation_time_s:.1f} s** |"  # type: ignore[attr-defined]
            )
    print()


def table_modes(root: Path) -> None:
    print("Table 2: both modes from their stored responses (warm), target at every line")
    print()
    print(
        "| level per line | type A target | binds at (lines) | multisine | stepped sine "
        "(best block) | ratio | cold: multisine / stepped |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- |")
    # (mode, block): the multisine has one setting, the stepped sine one per block length
    variants = [(Mode.MULTISINE.value, 0.25)]
    variants += [(Mode.STEPPED_SINE.value, b) for b in STEPPED_BLOCKS_S]
    for level in LEVELS:
        plan = plan_of(level)
        stores = {v: ResponseStore(root / f"{v[0]}-{v[1]:g}-{level:g}") for v in variants}
        for target in TARGETS:
            cold: dict[tuple[str, float], float] = {}
            warm: dict[tuple[str, float], float] = {}
            binds = 0
            for variant, store in stores.items():
                mode, block = variant
                if target == TARGETS[0]:  # the first run of this level fills the store
                    finished, _ = one(store, plan, target, mode, block)
                    cold[variant] = finished.record.excitation_time_s  # type: ignore[attr-defined]
                finished, p = one(store, plan, target, mode, block)
                warm[variant] = finished.record.excitation_time_s  # type: ignore[attr-defined]
                if mode == Mode.MULTISINE and p.first_type_a is not None:
                    binds = int(np.sum(p.first_type_a > target))
            multi = warm[variants[0]]
            best = min(variants[1:], key=lambda v: warm[v])
            cold_text = ""
            if cold:
                best_cold = min(cold[v] for v in variants[1:])
                cold_text = f"{cold[variants[0]]:.1f} s / {best_cold:.1f} s"
            print(
                f"| {level:g} m/s^2 | {100 * target:g} % | {binds}/{len(plan.lines)} "
                f"(at {MIN_PERIODS['periodic']} periods) | {multi:.1f} s | "
                f"{warm[best]:.1f} s ({best[1]:g} s) | **{warm[best] / multi:.1f}** | "
                f"{cold_text} |"
            )
    print()


def main() -> None:
    np.seterr(all="ignore")
    with tempfile.TemporaryDirectory(prefix="accelcal-bench-") as root:
        table_phases(Path(root))
        table_modes(Path(root))


if __name__ == "__main__":
    main()
