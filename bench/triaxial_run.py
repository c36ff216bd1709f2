"""The triaxial DUT end to end on the simulated stand (issue 36 point 3), over seeds: per seed
three orientation runs (`accelcal run --stand sim/stand-triaxial.toml --dut T=SN
--orientation x|y|z`, the real command) and their TriaxialResult (what `certificate
--triaxial` states), each statement against sim/triaxial.py's S: the count within U of the
main-axis sensitivities and phases, the transverse ratios' magnitudes, the largest transverse
sensitivity and its angle; and the simulated excitation seconds per orientation. Counts and
simulated seconds do not depend on the machine's load.

Usage: python -m bench.triaxial_run [--seeds N] [--first S]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import logging
import os
import tempfile
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

STAND = Path(__file__).parents[1] / "sim" / "stand-triaxial.toml"


def _wrap(deg: np.ndarray) -> np.ndarray:
    return (np.asarray(deg) + 180.0) % 360.0 - 180.0


def one_seed(seed: int, root: Path, counts: dict[str, list[int]], seconds: list[float]) -> None:
    """Three orientation runs of `seed` under `root`, their statements counted."""
    from app.certificate.triaxial_issue import triaxial_result_of, triaxial_runs
    from app.cli import main
    from app.records.run_folder import load_run
    from sim.triaxial import example_sensor

    out = root / f"seed-{seed}"
    batches = []
    for o in "xyz":
        argv = ["run", "--stand", str(STAND), "--dut", "T=TRI-1", "--orientation", o]
        argv += ["--seed", str(seed), "--out", str(out), "--technician", "bench"]
        with contextlib.redirect_stdout(io.StringIO()):
            status = main(argv)
        if status != 0:
            raise SystemExit(f"seed {seed} orientation {o}: exit {status}")
        new = [p for p in out.iterdir() if (p / "batch.json").exists() and p not in batches]
        batches.append(new[0])
    runs = triaxial_runs(batches)
    for o in "xyz":
        seconds.append(float(load_run(runs.folders[o][o]).excitation_time_s))
    result = triaxial_result_of(runs)
    s = example_sensor().matrix(result.frequency_hz)

    def add(kind: str, error: np.ndarray, expanded: np.ndarray) -> None:
        ok = np.isfinite(error) & np.isfinite(expanded)
        counts.setdefault(kind, [0, 0])
        counts[kind][0] += int(np.sum(np.abs(error[ok]) <= expanded[ok]))
        counts[kind][1] += int(ok.sum())

    for j, axis in enumerate(result.axes):
        m = axis.sensitivity_mv_per_ms2
        add("main", m.value - np.abs(s[:, j, j]), m.expanded)
        ph = axis.phase_deg
        add("main phase", _wrap(ph.value - np.degrees(np.angle(s[:, j, j]))), ph.expanded)
        k, k2 = (j + 1) % 3, (j + 2) % 3
        t = {o: s[:, j, o] / s[:, j, j] for o in (k, k2)}
        for ratio in axis.transverse:
            o = "xyz".index(ratio.towards.value)
            r = ratio.magnitude_percent
            add("ratio", r.value - 100 * np.abs(t[o]), r.expanded)
        big = axis.largest_percent
        add("largest", big.value - 100 * np.hypot(np.abs(t[k]), np.abs(t[k2])), big.expanded)
        angle = axis.angle_deg
        truth = np.degrees(np.arctan2(t[k2].real, t[k].real))
        add("angle", _wrap(angle.value - truth), angle.expanded)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--first", type=int, default=100)
    parser.add_argument("--smoke", action="store_true", help="one seed (CI: runs to its end)")
    args = parser.parse_args(argv)
    if args.smoke:
        args.seeds = 1
    if not 1 <= args.seeds <= 1000:
        parser.error("--seeds: between 1 and 1000")
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    log.setLevel(logging.INFO)  # the runs' own logs at WARNING
    counts: dict[str, list[int]] = {}
    seconds: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        os.environ.setdefault("ACCELCAL_DATA_DIR", str(Path(tmp) / "data"))
        for seed in range(args.first, args.first + args.seeds):
            one_seed(seed, Path(tmp), counts, seconds)
    log.info("%d triaxial calibrations (3 orientation runs each), seeds %d-%d",
             args.seeds, args.first, args.first + args.seeds - 1)  # fmt: skip
    log.info("simulated excitation per orientation run: %.1f-%.1f s (mean %.1f s)",
             min(seconds), max(seconds), float(np.mean(seconds)))  # fmt: skip
    for kind, (hit, total) in counts.items():
        log.info("%-11s within U: %d of %d (%.1f %%)", kind, hit, total, 100 * hit / total)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
