"""Coverage of the per-DUT U over batch runs on the fixture's physics (issue 36, acceptance 1).

For each block of seeds (block b: seeds b * 10000 + 1 .. + N), one unpaced batch of four piezo
DUTs at the positions A-D of a fixture stand file (default sim/stand-fixture4-physics.toml: the
block's rocking, bending and crosstalk from sim/fixture.py, its mounting drawn per run from the
seed), a fresh stand response per run. The stand itself runs at its nominal values (no draws
from the stand file's [simulation] map: those come from the budget the analysis states); each
member's truth is, as in bench/coverage_true.py, a realisation of sim/true_stand.py's own table
(its seed from the run's seed and the position) put on the member's recorded DUT channel, then
the member analysed as `accelcal analyze` analyses it (its run's estimator, its budget with the
position's terms). Per position and line: how many runs stated the line, and the fraction whose
sensitivity lies within its expanded uncertainty U of the DUT's own truth (its sensor model's
sensitivity: the fixture's motion and the true stand's deviations are errors of the comparison,
not of the DUT), the phase likewise. Prints the table per block and pooled, and every line
outside 93-97.5 % with the stated relative-motion u there against the root mean square of the
true one over the runs' mountings (the term to look at when a line misses). Coverage is a count:
the same on any machine. The wall time per run is printed only with `uptime`'s load average.

A 95 % coverage's binomial standard deviation over 200 runs is 1.5 %; a line is flagged on the
pooled runs of all blocks, each block's figure shown beside it.

Run: python bench/coverage_fixture.py [--runs N] [--blocks B] [--periods P] [--stand FILE]
[--smoke]   (--smoke: two runs in one block, one period; figures not meaningful)
     python bench/coverage_fixture.py --pool OUT0 OUT1   (pools the printed outputs of runs of
     different blocks, e.g. two processes at once: the pooled table, each cell's Clopper-Pearson
     95 % interval, the cells outside the band)
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import math
import os
import shutil
import signal
import sys
import tempfile
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.io.hdf5 import read_recording  # noqa: E402
from app.procedure.analysis import analyze  # noqa: E402
from app.procedure.batch import MemberChoice, execute_batch  # noqa: E402
from app.procedure.request import RunRequest  # noqa: E402
from app.records.run_start import RunStart  # noqa: E402
from app.stand import config as stand_config  # noqa: E402
from sim.fixture import FixtureModel  # noqa: E402
from sim.true_stand import TrueStand  # noqa: E402

log = logging.getLogger("coverage_fixture")
LOW, HIGH = 0.93, 0.975  # the band for the coverage of U at every line
DUT_MASS_G = 10.0  # the simulated piezo DUT's (sim.models.SensorModel.mass_g)
BLOCK = 10_000  # seeds of block b start at b * BLOCK + 1


@dataclass
class Tally:
    """One position's counts per line (nominal frequency, Hz)."""

    stated: dict[float, int] = field(default_factory=lambda: defaultdict(int))
    within: dict[float, int] = field(default_factory=lambda: defaultdict(int))
    phase_within: dict[float, int] = field(default_factory=lambda: defaultdict(int))
    motion_sq: dict[float, float] = field(default_factory=lambda: defaultdict(float))
    mountings: dict[float, int] = field(default_factory=lambda: defaultdict(int))

    def add(self, other: Tally) -> None:
        """Pool `other`'s counts into this one."""
        for mine, theirs in (
            (self.stated, other.stated),
            (self.within, other.within),
            (self.phase_within, other.phase_within),
            (self.motion_sq, other.motion_sq),
            (self.mountings, other.mountings),
        ):
            for key, value in theirs.items():
                mine[key] += value  # type: ignore[index]


def plan(max_hz: float) -> dict[str, object]:
    """The run request's plan: the piezo preset's lines (10-2500 Hz) at `max_hz` <= 2500, else
    the ISO 266 lines 10 Hz-`max_hz` (the ISO 16063-21 band reaches 10 kHz) sampled at 2.56 x
    `max_hz` rounded up to 1.024 kHz, a period of one second."""
    if max_hz <= 2500.0:
        return {}
    from dsp import iso266

    fs = 1024.0 * math.ceil(2.56 * max_hz / 1024.0)
    return {
        "frequencies_hz": tuple(iso266.nominal_frequencies(10.0, max_hz)),
        "sample_rate_hz": fs,
        "period_samples": int(fs),
    }


def run_block(
    block: int, runs: int, periods: int | None, stand: Path, out: Path, max_hz: float
) -> tuple[dict[str, Tally], list[float]]:
    """The runs of one block of seeds: per position its tally; the wall time per run (s)."""
    config = stand_config.load(stand)
    positions = [p.name for p in config.fixture.positions] if config.fixture else []
    tallies = {p: Tally() for p in positions}
    walls = []
    try:
        for seed in range(block * BLOCK + 1, block * BLOCK + runs + 1):
            one_run(seed, stand, out / str(seed), extra_of(periods, max_hz), config, tallies, walls)
    except KeyboardInterrupt:  # SIGINT or SIGTERM: report the runs done
        log.warning("block %d: stopped after %d run(s)", block, len(walls))
    return tallies, walls


def extra_of(periods: int | None, max_hz: float) -> dict[str, object]:
    """The request's plan and periods (None: the request's default)."""
    extra: dict[str, object] = plan(max_hz)
    if periods is not None:
        extra["periods"] = periods
    return extra


def one_run(
    seed: int,
    stand: Path,
    folder: Path,
    extra: dict[str, object],
    config: stand_config.StandConfig,
    tallies: dict[str, Tally],
    walls: list[float],
) -> None:
    """One batch run of `seed` into `folder`, counted into `tallies` (then removed)."""
    fixture = FixtureModel.from_stand(config.raw)
    block_g = 1000.0 * config.fixture.mass_kg if config.fixture is not None else 0.0
    positions = list(tallies)
    counted = {p: Tally() for p in positions}  # this run's counts, added when it is whole
    request = RunRequest(
        stand_file=stand,
        out=folder,
        seed=seed,
        stored_response=False,
        sim_systematic=False,  # the truth of the stand's own terms: the true stand, below
        **extra,  # type: ignore[arg-type]
    )
    choices = [MemberChoice(p, f"S{seed}-{p}") for p in positions]
    start = time.perf_counter()
    batch = execute_batch(request, choices, config=config)
    walls.append(time.perf_counter() - start)
    for index, (choice, finished) in enumerate(batch.members):
        if finished.results is None:
            log.warning(
                "seed %d %s: %s %s",
                seed,
                choice.position,
                finished.status,
                finished.abort_reason,
            )
            continue
        lines, truth = true_stand_lines(
            folder / str(finished.record.run_id), member_seed(seed, index)
        )
        tally = counted[choice.position]
        motion = None
        if fixture is not None:
            masses = {p: DUT_MASS_G for p in positions}
            mount = fixture.mounted(seed, masses, block_g)
            f = np.array([ln.frequency_hz for ln in lines])
            ratio = mount.motion_ratio(choice.position, f)
            motion = 100.0 * (np.abs(ratio) - 1.0)
        for i, (line, value, phase) in enumerate(
            zip(
                lines,
                truth.sensitivity_mv_per_ms2,
                truth.phase_deg,
                strict=True,
            )
        ):
            if line.sensitivity_mv_per_ms2 is None:
                continue
            key = line.nominal_frequency_hz
            error = abs(line.sensitivity_mv_per_ms2 - value)
            tally.stated[key] += 1
            tally.within[key] += error <= line.expanded_uncertainty_mv_per_ms2
            phase_error = abs((line.phase_deg - phase + 180.0) % 360.0 - 180.0)
            tally.phase_within[key] += phase_error <= line.phase_expanded_uncertainty_deg
            if motion is not None:
                tally.motion_sq[key] += float(motion[i]) ** 2
                tally.mountings[key] += 1
    shutil.rmtree(folder, ignore_errors=True)
    for name, tally in counted.items():
        tallies[name].add(tally)


def member_seed(seed: int, index: int) -> int:
    """The true stand's seed for member `index` of the run of `seed` (none of
    bench/coverage_true.py's seeds, which stay under 10^6)."""
    return 1_000_000 + 16 * seed + index


def true_stand_lines(run: Path, true_seed: int) -> tuple[list, Any]:  # type: ignore[type-arg]
    """The member run's lines analysed as `accelcal analyze` analyses it (its estimator), with
    the true stand of `true_seed` put on its recorded DUT channel; and the DUT's truth the
    recording names (its sensor model's sensitivity and phase per line)."""
    recording = read_recording(run / "recording.h5")
    truth = recording.truth
    assert truth is not None
    true = TrueStand.draw(true_seed)
    recording = dataclasses.replace(
        recording, dut_v=true.apply(recording.dut_v, recording.sample_rate_hz)
    )
    estimator = RunStart.read(run).settings.get("estimator")
    kwargs = {"estimator": str(estimator)} if estimator else {}
    return list(analyze(recording, **kwargs).results.lines), truth


def stated_motion(stand: Path) -> dict[str, list[list[float]]]:
    """Each position's stated relative_motion rows (Hz, percent) as the stand file has them."""
    config = stand_config.load(stand)
    entries = config.raw.get("fixture", {}).get("position", [])
    return {e["name"]: e.get("relative_motion", []) for e in entries}


def report(blocks: list[dict[str, Tally]], stand: Path) -> int:
    """Print the coverage tables and the lines outside the band; how many are outside."""
    pooled: dict[str, Tally] = defaultdict(Tally)
    for tallies in blocks:
        for name, tally in tallies.items():
            pooled[name].add(tally)
    rows = stated_motion(stand)
    outside = []
    for name, tally in pooled.items():
        print(f"\nposition {name}: coverage of U per line (magnitude; phase), blocks then pooled")
        print(
            f"{'f Hz':>8} {'runs':>5} "
            + " ".join(f"{'blk' + str(b):>6}" for b in range(len(blocks)))
            + f" {'pooled':>7} {'phase':>7} {'u_rm %':>8} {'rms %':>8}"
        )
        for key in sorted(tally.stated):
            n = tally.stated[key]
            share = tally.within[key] / n
            per_block = []
            for tallies in blocks:
                t = tallies[name]
                per_block.append(
                    f"{t.within[key] / t.stated[key]:6.3f}" if t.stated.get(key) else f"{'-':>6}"
                )
            u_rm = _at(rows.get(name, []), key)
            rms = (
                math.sqrt(tally.motion_sq[key] / tally.mountings[key])
                if tally.mountings.get(key)
                else math.nan
            )
            phase = tally.phase_within[key] / n
            print(
                f"{key:8g} {n:5d} {' '.join(per_block)} {share:7.3f} {phase:7.3f} "
                f"{u_rm:8.3g} {rms:8.3g}"
            )
            if not LOW <= share <= HIGH:
                outside.append(f"{name} {key:g} Hz: {share:.3f} of {n} (magnitude)")
            if not LOW <= phase <= HIGH:
                outside.append(f"{name} {key:g} Hz: {phase:.3f} of {n} (phase)")
    print(f"\nlines outside {LOW:.1%}-{HIGH:.1%} (pooled): {len(outside)}")
    for line in outside:
        print(f"  {line}")
    return len(outside)


def _at(rows: list[list[float]], frequency_hz: float) -> float:
    """A stated table's value (log-log interpolated, flat outside), NaN without rows."""
    if not rows:
        return math.nan
    f = np.asarray(rows, dtype=np.float64)
    x = math.log(frequency_hz)
    return float(np.exp(np.interp(x, np.log(f[:, 0]), np.log(f[:, 1]))))


def _read_tables(path: Path) -> dict[tuple[str, float], tuple[int, int, int]]:
    """A printed run's per-block table: (position, line Hz) -> (runs, within U, phase within)."""
    import re

    out: dict[tuple[str, float], tuple[int, int, int]] = {}
    position = None
    row = re.compile(r"\s+([\d.]+)\s+(\d+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)\s")
    for text in path.read_text(encoding="utf-8").splitlines():
        head = re.match(r"position (\w+):", text)
        if head:
            position = head.group(1)
            continue
        found = row.match(text + " ")
        if found and position is not None:
            n = int(found.group(2))
            key = (position, float(found.group(1)))
            out[key] = (n, round(float(found.group(4)) * n), round(float(found.group(5)) * n))
    return out


def pool(paths: list[Path]) -> int:
    """The pooled coverage of the runs whose printed output `paths` are (one block each: their
    seeds must differ), with each pooled cell's Clopper-Pearson 95 % interval; how many cells
    lie outside the band."""
    from scipy.stats import beta

    tables = [_read_tables(p) for p in paths]
    keys = sorted(set.intersection(*(set(t) for t in tables)))
    outside, excluded = [], []
    print(f"pooled over {', '.join(str(p) for p in paths)}: magnitude (phase) per position")
    positions = sorted({k[0] for k in keys})
    print(f"{'f Hz':>8} " + " ".join(f"{p:>15}" for p in positions))
    for f in sorted({k[1] for k in keys}):
        cells = []
        for position in positions:
            counts = [t[(position, f)] for t in tables if (position, f) in t]
            n = sum(c[0] for c in counts)
            shares = []
            for q, name in ((1, "magnitude"), (2, "phase")):
                hits = sum(c[q] for c in counts)
                share = hits / n
                lo = 0.0 if hits == 0 else float(beta.ppf(0.025, hits, n - hits + 1))
                hi = 1.0 if hits == n else float(beta.ppf(0.975, hits + 1, n - hits))
                if not LOW <= share <= HIGH:
                    outside.append(f"{position} {f:g} Hz {name}: {share:.3f} [{lo:.3f}, {hi:.3f}]")
                if hi < LOW or lo > HIGH:
                    excluded.append(f"{position} {f:g} Hz {name}")
                shares.append(share)
            cells.append(f"{shares[0]:.3f} ({shares[1]:.3f})")
        print(f"{f:8g} " + " ".join(f"{c:>15}" for c in cells))
    total = 2 * len(keys)
    print(f"\ncells {total}; outside {LOW:.1%}-{HIGH:.1%}: {len(outside)} (interval in brackets)")
    for line in outside:
        print(f"  {line}")
    print(f"cells whose 95 % interval lies outside the band: {len(excluded)} {excluded}")
    return len(outside)


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def main() -> int:
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=200, help="batch runs per block of seeds")
    parser.add_argument("--blocks", type=int, default=2, help="blocks of seeds")
    parser.add_argument("--first-block", type=int, default=0, help="first block")
    parser.add_argument("--periods", type=int, default=None, help="(default: the request's)")
    parser.add_argument("--stand", type=Path, default=ROOT / "sim" / "stand-fixture4-physics.toml")
    parser.add_argument(
        "--max-hz", type=float, default=10_000.0, help="the plan's top line (<= 2500: the preset)"
    )
    parser.add_argument("--smoke", action="store_true")
    parser.add_argument(
        "--pool", type=Path, nargs="+", help="pool the printed outputs of runs of other blocks"
    )
    args = parser.parse_args()
    if args.pool:
        missing = [p for p in args.pool if not p.is_file()]
        if missing:
            print(f"--pool: {missing[0]} is not a file", file=sys.stderr)
            return 2
        return 1 if pool(args.pool) else 0
    runs, blocks, periods = (2, 1, 1) if args.smoke else (args.runs, args.blocks, args.periods)
    if runs < 1 or blocks < 1:
        print("--runs and --blocks: at least 1", file=sys.stderr)
        return 2
    if not args.stand.is_file():
        print(f"--stand: {args.stand} is not a file", file=sys.stderr)
        return 2
    out = Path(tempfile.mkdtemp(prefix="coverage-fixture-"))
    results = []
    walls: list[float] = []
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        for block in range(args.first_block, args.first_block + blocks):
            tallies, block_walls = run_block(block, runs, periods, args.stand, out, args.max_hz)
            results.append(tallies)
            walls += block_walls
            if len(block_walls) < runs:
                break  # stopped: no further block
    finally:
        shutil.rmtree(out, ignore_errors=True)
    print(
        f"{args.stand.name}: {len(results)} block(s) from {args.first_block}, "
        f"{len(walls)} of {blocks * runs} batch run(s) done, periods "
        f"{periods if periods is not None else 'default'}, unpaced"
    )
    outside = report(results, args.stand)
    load = os.getloadavg()
    print(
        f"\nwall per batch run: median {float(np.median(walls)):.1f} s over {len(walls)} "
        f"(load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}: loaded figures mean little)"
    )
    return 1 if outside and not args.smoke else 0


if __name__ == "__main__":
    sys.exit(main())
