"""Excitation time to a type A target: multisine against stepped sine (SPEC.md s.12, issue 14).

Both modes on the same simulated stand (nominal values, seed 5), same estimator, the target at
every line, each with the settings that give it its best:
- multisine: equalisation from the stand's stored response (checked first by a short burst
  at 20 % of the level inside one period, issue 34; then its first settled step), the two
  settled periods reused as the first acquired ones, acquisition until the target (at least
  3 periods), a fade-out of 1.5 cycles of the lowest line (4 before issue 34);
- stepped sine: on its own block-compatible frequencies (issue 32 point 8: each line within
  2 % of nominal as the multisine's low-frequency grid, inside the nominal span and off the
  mains harmonics, on the bin whose block of whole cycles of the line and of the mains is
  shortest: dsp.sinefit.block_compatible_grid), blocks of at least 0.05, 0.1 or 0.25 s (the
  best of the three is shown for each row), each line's level loop started from its own
  stored response, three-parameter sine fits, settled blocks reused, the same fade-out rule
  per line.
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

3. issue 26: the lpm estimator (one record after a short fade-in, the transient estimated;
   dsp.lpm_record, app.procedure.record_run) on the seed's lines at 5 m/s^2 and 0.2 % type A,
   cold and warm, against the periodic multisine and the fair stepped sine (warm, best block);
   where the warm excitation goes per phase, and (issue 34) the warm lpm estimate with the
   default one-cycle fade-in against a fade-in of a whole period on the same seed;
4. issue 26: 0.4-8 Hz on the long-stroke exciter with the README's options (the plan
   app.procedure.planning builds: ISO 266 lines within 2 % of nominal and inside 0.4-8 Hz,
   constant displacement below 3 Hz, 1.5 m/s^2 above; the DUT's nominal 10.2 mV/(m/s^2) sizes
   its input range): the lpm multisine against the fair stepped sine, both warm, every line
   checked against the truth (lines outside U, the worst error in U, and the lines not stated
   or whose resolution keeps them from a conformity statement); the simulated table's travel
   against the preflight's prediction (fades included) and the stroke.

Run: python bench/excitation_time.py [--lpm] [--smoke]   (about three minutes of CPU;
--lpm: tables 3 and 4 only; --smoke: one run a table, table 4 left out: checks it runs)
"""

from __future__ import annotations

import sys
import tempfile
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.io.vocabulary import Mode, RunStatus
from app.procedure import PeriodBlock, PeriodEstimate, Procedure, RunSettings
from app.procedure.phase_store import stored_phases
from app.procedure.planning import GRID_TOLERANCE, PlanRequest, build_plan
from app.procedure.preflight import check_preflight
from app.procedure.run import with_exciter
from app.records.warnings import WarningKind, classify
from app.stand.config import load
from app.stand.open import open_stand
from app.stand.response import ResponseStore
from app.stand.simulated import exciter_stroke_m
from dsp import iso266
from dsp.multisine import PRESETS, Line, Plan, make_plan, preset_plan
from dsp.sinefit import block_compatible_grid
from dsp.spectral import MIN_PERIODS
from sim.stand import MultiZoh

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
        return preset_plan("piezo", level_ms2=level, optimiser=stored_phases)
    preset = PRESETS["piezo"]
    return make_plan(
        preset.nominal_frequencies_hz,
        preset.sample_rate_hz,
        period_samples,
        level,
        preset.reference_frequency_hz,
    )


def stepped_plan(plan: Plan, block_s: float) -> Plan:
    """The fair stepped sine's plan for `plan`'s lines (SPEC s.12, issue 32 point 8): each
    line on the bin within GRID_TOLERANCE (2 %, as the multisine's low-frequency grid) of its
    nominal frequency, inside the nominal span and off the mains harmonics, whose block of
    whole cycles of the line and of the mains (at least `block_s`) is shortest
    (dsp.sinefit.block_compatible_grid); the same level per line as `plan`."""
    nominal = plan.nominal_frequencies_hz
    grid = block_compatible_grid(
        nominal,
        plan.sample_rate_hz,
        block_s,
        mains_hz=plan.mains_frequency_hz,
        mains_harmonics=plan.mains_harmonics,
        tolerance=GRID_TOLERANCE,
        within_hz=(float(nominal.min()), float(nominal.max())),
    )
    lines = tuple(
        Line(line.nominal_frequency_hz, f, b, line.amplitude_ms2, 0.0)
        for line, f, b in zip(plan.lines, grid.frequencies_hz, grid.bins, strict=True)
    )
    return Plan(
        plan.sample_rate_hz,
        grid.period_samples,
        lines,
        plan.reference_frequency_hz,
        plan.mains_frequency_hz,
        plan.mains_harmonics,
    )


def grid_text(plan: Plan) -> str:
    """The lines a stepped-sine plan plays, where they are off nominal (Hz)."""
    moved = [
        f"{line.nominal_frequency_hz:g} at {line.frequency_hz:.4g}"
        for line in plan.lines
        if abs(line.frequency_hz - line.nominal_frequency_hz) > 1e-9 * line.frequency_hz
    ]
    return ", ".join(moved) if moved else "every line at its nominal frequency"


class Phases:
    """Excitation per state (s) from the PeriodBlock events, and the type A per line at the
    minimum number of periods (from the first PeriodEstimate)."""

    def __init__(self, sample_rate_hz: float):
        self.fs = sample_rate_hz
        self.seconds: dict[str, float] = defaultdict(float)
        self.first_type_a: np.ndarray | None = None
        self.stand: object = None  # the stand the run used (its truth), set by `one`
        self.travel = (0.0, 0.0)  # the simulated table's lowest and highest displacement (m)

    def __call__(self, event: object) -> None:
        if isinstance(event, PeriodBlock):
            moving = np.flatnonzero(event.drive)
            if moving.size:
                self.seconds[str(event.state)] += (moving[-1] - moving[0] + 1) / self.fs
        elif isinstance(event, PeriodEstimate) and self.first_type_a is None:
            self.first_type_a = np.asarray(event.estimate.relative_type_a)


def one(
    store: ResponseStore,
    plan: Plan,
    target: float | None,
    mode: str,
    block_s: float = 0.25,
    *,
    estimator: str = "periodic",
    exciter: str | None = None,
    periods: int = 8,
    dut_nominal: float | None = None,
    fade_in_s: float | None = None,
) -> tuple[object, Phases]:
    """One run; its Finished event and its phases (the table's displacement in `Phases.travel`)."""
    config = with_exciter(CONFIG, exciter)
    stand = open_stand(config, dut="piezo", seed=5, systematic=False, exciter=exciter)
    phases = Phases(plan.sample_rate_hz)
    settings = RunSettings(
        mode=mode,
        target_type_a=target,
        max_acquisition_s=40000.0,
        dut_mass_g=10.0,
        stepped_block_s=block_s,
        estimator=estimator,
        periods=periods,
        dut_nominal_mv_per_ms2=dut_nominal,
        fade_in_s=fade_in_s,
    )
    process = MultiZoh.process

    def recording(self: MultiZoh, u: np.ndarray) -> dict[str, np.ndarray]:
        out = process(self, u)
        moved = out["displacement"]
        phases.travel = (
            min(phases.travel[0], float(moved.min())),
            max(phases.travel[1], float(moved.max())),
        )
        return out

    MultiZoh.process = recording  # type: ignore[method-assign]
    try:
        finished = Procedure(stand, plan, settings, listener=phases, response_store=store).run()
    finally:
        MultiZoh.process = process  # type: ignore[method-assign]
        stand.close()
    if finished.status != RunStatus.COMPLETE:
        raise SystemExit(f"{mode} at {target}: {finished.abort_reason}")
    phases.stand = stand
    return finished, phases


@dataclass(frozen=True)
class TruthCheck:
    """Each line of a run against the stand's truth: the stated lines farther than U, how
    many lines are stated, the largest error in U (magnitude, phase) over them, and the lines
    not stated (no value) or whose resolution warning blocks PASS (too few LSB)."""

    outside: tuple[str, ...]
    stated: int
    worst_u: tuple[float, float]
    held: tuple[str, ...]

    def text(self, count: int) -> str:
        """The table cell: stated lines outside U, the worst error, what is held back."""
        out = f"{len(self.outside)}/{self.stated}"
        if self.stated < count:
            out += f" stated of {count}"
        if self.outside:
            out += ": " + ", ".join(self.outside)
        out += f" (worst {self.worst_u[0]:.2f} U, phase {self.worst_u[1]:.2f} U)"
        if self.held:
            out += "; " + ", ".join(self.held)
        return out


def check_truth(finished: object, stand: object, plan: Plan, mode: str) -> TruthCheck:
    """The run's lines against the stand's truth (at the excitation's rms acceleration: the
    multisine's total, one line's in stepped sine)."""
    results = finished.results  # type: ignore[attr-defined]
    truth = stand.truth  # type: ignore[attr-defined]
    if mode == Mode.STEPPED_SINE:
        values = np.array(
            [
                truth(np.array([f]), a / np.sqrt(2))[0]
                for f, a in zip(plan.frequencies_hz, plan.amplitudes_ms2, strict=True)
            ]
        )
    else:
        values = truth(plan.frequencies_hz, float(np.sqrt(np.sum(plan.amplitudes_ms2**2) / 2)))
    outside, held = [], []
    unstated: list[float] = []  # the frequencies (nominal and actual) of lines not stated
    worst = [0.0, 0.0]
    for line, value in zip(results.lines, values, strict=True):
        if not line.stated:
            held.append(f"{line.nominal_frequency_hz:g} Hz not stated ({line.not_stated})")
            unstated += [line.nominal_frequency_hz, line.frequency_hz]
            continue
        e_mag = abs(line.sensitivity_mv_per_ms2 - abs(value)) / line.expanded_uncertainty_mv_per_ms2
        d_ph = (line.phase_deg - np.degrees(np.angle(value)) + 180) % 360 - 180
        e_ph = abs(d_ph) / line.phase_expanded_uncertainty_deg
        worst = [max(worst[0], e_mag), max(worst[1], e_ph)]
        if e_mag > 1 or e_ph > 1:
            outside.append(f"{line.nominal_frequency_hz:g} Hz ({e_mag:.1f} U, {e_ph:.1f} U phase)")
    for warning in results.warnings:
        if classify(warning).kind != WarningKind.ADC_RESOLUTION:
            continue
        label = warning.split(":", 1)[0].replace("line ", "")  # "0.406321 Hz"
        if not any(np.isclose(float(label.split()[0]), f) for f in unstated):
            held.append(f"{label} stated, its resolution blocks PASS")
    stated = sum(1 for line in results.lines if line.stated)
    return TruthCheck(tuple(outside), stated, (worst[0], worst[1]), tuple(held))


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
        stepped_plans = {block: stepped_plan(plan, block) for block in STEPPED_BLOCKS_S}
        stores = {v: ResponseStore(root / f"{v[0]}-{v[1]:g}-{level:g}") for v in variants}
        for target in TARGETS:
            cold: dict[tuple[str, float], float] = {}
            warm: dict[tuple[str, float], float] = {}
            binds = 0
            for variant, store in stores.items():
                mode, block = variant
                played = plan if mode == Mode.MULTISINE else stepped_plans[block]
                if target == TARGETS[0]:  # the first run of this level fills the store
                    finished, _ = one(store, played, target, mode, block)
                    cold[variant] = finished.record.excitation_time_s  # type: ignore[attr-defined]
                finished, p = one(store, played, target, mode, block)
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


def table_lpm(root: Path) -> None:
    print("Table 3: lpm on the seed's lines, piezo at 5 m/s^2, 0.2 % type A (excitation time)")
    print()
    print(
        "| estimator | cold | warm | periods | worst type A | lines outside U | warm stepped "
        "sine (best block) / warm |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- |")
    plan = plan_of(5.0)
    stepped: dict[float, tuple[float, TruthCheck, Plan]] = {}
    for block in STEPPED_BLOCKS_S:
        store = ResponseStore(root / f"lpm-stepped-{block:g}")
        played = stepped_plan(plan, block)
        one(store, played, 0.002, Mode.STEPPED_SINE, block)
        finished, q = one(store, played, 0.002, Mode.STEPPED_SINE, block)
        seconds = finished.record.excitation_time_s  # type: ignore[attr-defined]
        stepped[block] = (
            seconds,
            check_truth(finished, q.stand, played, Mode.STEPPED_SINE),
            played,
        )
    best_block = min(stepped, key=lambda b: stepped[b][0])
    best = stepped[best_block][0]
    where: dict[str, Phases] = {}
    for estimator in ("lpm", "periodic"):
        store = ResponseStore(root / f"lpm-{estimator}")
        periods = 1 if estimator == "lpm" else 8
        cold, _ = one(store, plan, 0.002, Mode.MULTISINE, estimator=estimator, periods=periods)
        warm, p = one(store, plan, 0.002, Mode.MULTISINE, estimator=estimator, periods=periods)
        where[estimator] = p
        if estimator == "lpm":
            lpm_warm = warm
        results = warm.results  # type: ignore[attr-defined]
        worst = max(line.relative_type_a for line in results.lines)
        checked = check_truth(warm, p.stand, plan, Mode.MULTISINE)
        w = warm.record.excitation_time_s  # type: ignore[attr-defined]
        print(
            f"| {estimator} | {cold.record.excitation_time_s:.1f} s | "  # type: ignore[attr-defined]
            f"**{w:.1f} s** | {results.periods} | {100 * worst:.4f} % | "
            f"{checked.text(len(plan.lines))} | {best:.1f} s / {w:.1f} s = **{best / w:.1f}** |"
        )
    print()
    for estimator, phases in where.items():
        parts = ", ".join(f"{state} {t:.2f} s" for state, t in phases.seconds.items() if t > 0)
        print(f"where the warm excitation goes, {estimator}: {parts}")
    print()
    # the LPM's transient term absorbs the short fade-in: the same warm run (same stand seed,
    # same stored response) with a fade-in of one whole period instead
    store = ResponseStore(root / "lpm-long-fade")
    one(store, plan, 0.002, Mode.MULTISINE, estimator="lpm", periods=1)
    long_run, _ = one(
        store, plan, 0.002, Mode.MULTISINE, estimator="lpm", periods=1, fade_in_s=plan.period_s
    )
    short_lines = lpm_warm.results.lines  # type: ignore[attr-defined]
    long_lines = long_run.results.lines  # type: ignore[attr-defined]
    mag = max(
        abs(a.sensitivity_mv_per_ms2 - b.sensitivity_mv_per_ms2) / a.expanded_uncertainty_mv_per_ms2
        for a, b in zip(short_lines, long_lines, strict=True)
    )
    phase = max(
        abs(a.phase_deg - b.phase_deg) / a.phase_expanded_uncertainty_deg
        for a, b in zip(short_lines, long_lines, strict=True)
    )
    print(
        f"fade-in of one cycle (0.1 s) against one of a whole period ({plan.period_s:g} s), lpm, "
        f"warm, same seed: largest difference {mag:.4f} U (magnitude), {phase:.4f} U (phase)"
    )
    print()
    print("The stepped sine, warm, 0.2 % type A at every line (block-compatible frequencies):")
    print()
    print("| blocks | excitation | lines it plays off nominal | lines outside U |")
    print("| --- | --- | --- | --- |")
    for block, (seconds, checked, played) in stepped.items():
        print(
            f"| >= {block:g} s | {seconds:.1f} s | {grid_text(played)} | "
            f"{checked.text(len(played.lines))} |"
        )
    print()


LOW_TARGET = 0.02  # type A at every line, both modes (the lpm's one period gives 0.2 %)
LOW_NOMINAL = 10.2  # mV/(m/s^2): the DUT's nominal sizes its input range (as in the README)
LOW_LEVEL_MS2 = 1.5  # the README's --level: the DUT on +-0.2 V, 0.4 Hz over 20 LSB (at 2: +-0.5 V)


def low_plan() -> Plan:
    """0.4-8 Hz on the long-stroke exciter: the plan `accelcal run` builds for the README's
    options (--frequencies 0.4,...,8 --reference-frequency 8 --sample-rate 200 --exciter
    long-stroke --profile displacement --corner 3 --level 1.5): the lpm's grid, lines within
    2 % of nominal and inside the nominal span (0.4 Hz at 0.406 Hz)."""
    return build_plan(
        PlanRequest(
            frequencies_hz=iso266.nominal_frequencies(0.4, 8.0),
            sample_rate_hz=200.0,
            level_ms2=LOW_LEVEL_MS2,
            reference_frequency_hz=8.0,
            profile="displacement",
            corner_hz=3.0,
        ),
        stroke_peak_to_peak_m=exciter_stroke_m("long-stroke"),
    )


def table_low(root: Path) -> None:
    plan = low_plan()
    print(
        f"Table 4: 0.4-8 Hz on the long-stroke exciter (period {plan.period_s:g} s at "
        f"{plan.sample_rate_hz:g} Hz), piezo, both warm"
    )
    print()
    print(f"| mode | setting ({100 * LOW_TARGET:g} % type A at every line) | excitation | "
          "lines outside U |")  # fmt: skip
    print("| --- | --- | --- | --- |")
    store = ResponseStore(root / "low-lpm")
    lpm = {"estimator": "lpm", "exciter": "long-stroke", "periods": 1, "dut_nominal": LOW_NOMINAL}
    one(store, plan, LOW_TARGET, Mode.MULTISINE, **lpm)  # type: ignore[arg-type]
    lpm_run, p = one(store, plan, LOW_TARGET, Mode.MULTISINE, **lpm)  # type: ignore[arg-type]
    lpm_s = lpm_run.record.excitation_time_s  # type: ignore[attr-defined]
    checked = check_truth(lpm_run, p.stand, plan, Mode.MULTISINE)
    config = with_exciter(CONFIG, "long-stroke")
    predicted = check_preflight(plan, config, None, LOW_NOMINAL).peaks
    travel_text = (
        f"table travel of the warm lpm run: {1e3 * (p.travel[1] - p.travel[0]):.1f} mm p-p "
        f"simulated, {1e3 * predicted.displacement_peak_to_peak_m:.1f} mm predicted with the "
        f"fades (steady orbit {1e3 * plan.predicted_peaks().displacement_peak_to_peak_m:.1f} mm), "
        f"stroke {1e3 * config.limits.displacement_peak_to_peak_m:g} mm; excitation "
        f"{lpm_s:.1f} s = {lpm_s / plan.period_s:.2f} periods"
    )
    print(
        f"| multisine | lpm, {lpm_run.results.periods} period(s), lines within 2 % of nominal "  # type: ignore[attr-defined]
        f"| **{lpm_s:.1f} s** | {checked.text(len(plan.lines))} |"
    )
    best: tuple[float, float, Phases] | None = None  # (seconds, block, phases)
    for block in STEPPED_BLOCKS_S:
        played = stepped_plan(plan, block)
        store = ResponseStore(root / f"low-stepped-{block:g}")
        settings = {"exciter": "long-stroke", "dut_nominal": LOW_NOMINAL}
        one(store, played, LOW_TARGET, Mode.STEPPED_SINE, block, **settings)  # type: ignore[arg-type]
        run, q = one(store, played, LOW_TARGET, Mode.STEPPED_SINE, block, **settings)  # type: ignore[arg-type]
        seconds = run.record.excitation_time_s  # type: ignore[attr-defined]
        checked = check_truth(run, q.stand, played, Mode.STEPPED_SINE)
        print(
            f"| stepped sine | blocks >= {block:g} s, block-compatible frequencies "
            f"({grid_text(played)}) | {seconds:.1f} s | {checked.text(len(played.lines))} |"
        )
        if best is None or seconds < best[0]:
            best = (seconds, block, q)
    assert best is not None
    print()
    print(
        "low-frequency ratio, fair stepped sine (best block) / lpm multisine: "
        f"**{best[0] / lpm_s:.1f}**"
    )
    print()
    for label, phases in (("lpm multisine", p), (f"stepped sine (>= {best[1]:g} s)", best[2])):
        parts = ", ".join(f"{state} {t:.1f} s" for state, t in phases.seconds.items() if t > 0)
        print(f"where the excitation goes, {label}: {parts}")
    print()
    print(travel_text)
    print()


def main() -> None:
    np.seterr(all="ignore")
    with tempfile.TemporaryDirectory(prefix="accelcal-bench-") as root:
        if "--lpm" not in sys.argv:
            table_phases(Path(root))
            table_modes(Path(root))
        table_lpm(Path(root))
        if not SMOKE:  # 0.4-8 Hz: minutes of simulated excitation
            table_low(Path(root))


if __name__ == "__main__":
    main()
