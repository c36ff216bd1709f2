"""Several DUTs in one run on a multiplexed DAQ (issue 36): each DUT's phase against its sensor
model's truth, corrected with its own channel's delay (as the run stores it) and, for
comparison, re-analysed with the stand file's single daq.skew_s (the first DUT channel's).

For seeds 1..S, one batch of four piezo DUTs at positions A-D of a fixture stand file (default
sim/stand-fixture4.toml: the simulated DAQ samples the n-th DUT channel n x 4 us after the
reference), --periods P. Per position and correction: the delay used (us), the phase lines
stated, how many lie within U of the truth, and the worst |error| / U with its line. Counts
only: no wall time.

Run: python bench/batch_phase.py [--seeds S] [--periods P] [--stand FILE] [--smoke]
(--smoke: one seed, one period; figures not meaningful)
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.io.hdf5 import read_recording
from app.procedure.analysis import analyze
from app.procedure.batch import MemberChoice, execute_batch
from app.procedure.request import RunRequest
from app.stand import config as stand_config

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--periods", type=int, default=4)
    parser.add_argument("--stand", type=Path, default=ROOT / "sim" / "stand-fixture4.toml")
    parser.add_argument("--smoke", action="store_true")
    args = parser.parse_args()
    seeds = 1 if args.smoke else args.seeds
    periods = 1 if args.smoke else args.periods
    config = stand_config.load(args.stand)
    out = Path(tempfile.mkdtemp(prefix="batch-phase-"))
    stated: dict[tuple[str, str], int] = defaultdict(int)
    within: dict[tuple[str, str], int] = defaultdict(int)
    worst: dict[tuple[str, str], tuple[float, float]] = defaultdict(lambda: (0.0, 0.0))
    delay: dict[tuple[str, str], float] = {}
    for seed in range(1, seeds + 1):
        request = RunRequest(
            stand_file=args.stand, out=out, seed=seed, periods=periods, stored_response=False
        )
        choices = [MemberChoice(p, f"S{seed}-{p}") for p in "ABCD"]
        batch = execute_batch(request, choices, config=config)
        for choice, finished in batch.members:
            if finished.results is None:
                print(f"seed {seed} {choice.position}: {finished.status} {finished.abort_reason}")
                continue
            recording = read_recording(out / str(finished.record.run_id) / "recording.h5")
            assert recording.truth is not None and recording.chain.skew_s is not None
            for how, skew in (("own", recording.chain.skew_s), ("daq.skew_s", config.skew_s)):
                chain = dataclasses.replace(recording.chain, skew_s=skew)
                results = analyze(dataclasses.replace(recording, chain=chain)).results
                key = (choice.position, how)
                delay[key] = skew
                for line, truth in zip(results.lines, recording.truth.phase_deg, strict=True):
                    u = line.phase_expanded_uncertainty_deg
                    if line.phase_deg is None or u is None or not math.isfinite(u) or u <= 0:
                        continue
                    error = abs((line.phase_deg - truth + 180.0) % 360.0 - 180.0)
                    stated[key] += 1
                    within[key] += error <= u
                    if error / u > worst[key][0]:
                        worst[key] = (error / u, line.frequency_hz)
    print(f"{args.stand.name}: {seeds} seed(s), {periods} period(s)")
    print("position  correction  delay us  phase lines  within U  worst |error|/U (at Hz)")
    for position in "ABCD":
        for how in ("own", "daq.skew_s"):
            key = (position, how)
            ratio, at = worst[key]
            print(
                f"{position:>8}  {how:>10}  {1e6 * delay.get(key, math.nan):>8.3g}  "
                f"{stated[key]:>11}  {within[key]:>8}  {ratio:>8.3f} ({at:g})"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
