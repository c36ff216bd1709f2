"""A live LPM run to a type A target: work, wall time and peak memory against its length
(issue 34, the live path of point 4).

Each run is `accelcal run --sim --dut capacitive --estimator lpm --target-ua 0.05%
--max-time <2 P> s --seed 1`: the capacitive DUT's noise cannot reach 0.05 %, so the run goes
to its time bound, P periods of 2 s. A 2-period run first stores the stand's response, so every
run measured is warm. Each run is made in a fresh interpreter, twice: once for
its wall time and peak RSS (getrusage ru_maxrss; "extra" is the peak less a fresh process that
imports the CLI), once under tracemalloc for the peak Python and numpy allocate. The work is
counted, not timed: the periods the LPM estimates read in all (a whole record of p periods
counts p, a period fed to a batched record counts 1), so it does not depend on the machine's
load; memory does not either. Wall times are ratios to the shortest run of the same
invocation (absolute seconds are printed with the load average: the lead re-measures them at
idle).

`--also PATH` runs the same runs with another checkout's code (e.g. a worktree of main) for
the before/after figures.

`--parts` prints where the memory goes, in this process: the tracemalloc peak of the whole
record's estimate (dsp.lpm_record.record_estimate) of 10, 13 and 16 periods and of a batched
record (BatchedRecord: feeding a 16-period batch, then the estimate) of the capacitive plan on
synthetic periods, and the wall time of feeding 64 periods (a ratio to nothing: for the lead).
`--compare FOLDER` prints, for a stored lpm run folder, how far the batched estimate's type A
and H are from the whole record's (the stopping rule's type A over 16 periods).

Run: python bench/lpm_live.py [P ...]    (default 10 30 60)
Smoke: python bench/lpm_live.py --smoke  (2 and 3 periods: it runs, figures not meaningful)
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
log = logging.getLogger("lpm_live")

CHILD = r"""
import json, os, resource, sys, time, tracemalloc
mode, periods, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
from app.cli import main
import dsp.lpm_record as record
work = {"periods": 0, "estimates": 0}
whole = record.record_estimate
def counted(reference, dut, plan, **kw):
    work["periods"] += len(reference); work["estimates"] += 1
    return whole(reference, dut, plan, **kw)
record.record_estimate = counted
for name in ("dsp.lpm_live", "app.procedure.record_run"):
    try:
        module = __import__(name, fromlist=["x"])
    except ImportError:
        continue
    if hasattr(module, "record_estimate"):
        module.record_estimate = counted
try:
    from dsp.lpm_live import LiveRecord
    close = LiveRecord.close
    def closed(self):
        work["periods"] += self.batch_periods_fed
        return close(self)
    LiveRecord.close = closed
except ImportError:
    pass
estimate = record.BatchedRecord.estimate if hasattr(record, "BatchedRecord") else None
if estimate is not None:
    def batched(self):
        work["estimates"] += 1
        return estimate(self)
    record.BatchedRecord.estimate = batched
if mode == "baseline":
    code, seconds, peak, result = 0, 0.0, 0, {}
else:
    if mode == "traced":
        tracemalloc.start()
    argv = ["run", "--sim", "--dut", "capacitive", "--estimator", "lpm", "--target-ua",
            "0.05%", "--max-time", f"{2 * periods}s", "--seed", "1", "--json", "--out", out]
    import io
    printed = io.StringIO()
    stdout, sys.stdout = sys.stdout, printed
    t0 = time.perf_counter()
    code = main(argv)
    seconds = time.perf_counter() - t0
    sys.stdout = stdout
    peak = tracemalloc.get_traced_memory()[1] if mode == "traced" else 0
    run_id = json.loads(printed.getvalue())["run_id"]
    stored = json.loads(open(os.path.join(out, run_id, "results.json")).read())
    result = stored.get("results") or {}
print(json.dumps({"code": code, "seconds": seconds, "traced_bytes": peak,
                  "rss_kib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                  "periods": result.get("periods"), "work": work}))
"""


def child(mode: str, periods: int, code_root: Path, env: dict[str, str]) -> dict:
    """One fresh interpreter on `code_root`'s code: a run of `periods` periods (or only the
    imports: "baseline"), its figures."""
    with tempfile.TemporaryDirectory() as out:
        done = subprocess.run(
            [sys.executable, "-c", CHILD, mode, str(periods), out],
            capture_output=True,
            text=True,
            env={**env, "PYTHONPATH": str(code_root)},
            cwd=code_root,
            check=False,
        )
    if done.returncode != 0:
        raise SystemExit(f"run child failed ({done.returncode}): {done.stderr.strip()[-600:]}")
    result = json.loads(done.stdout.strip().splitlines()[-1])
    if result["code"] != 0:
        raise SystemExit(f"accelcal run ({periods} periods): exit {result['code']}")
    return result


def measure(code_root: Path, counts: list[int], env: dict[str, str]) -> None:
    """Print the figures of runs of `counts` periods on `code_root`'s code."""
    base = child("baseline", 0, code_root, env)["rss_kib"]
    child("timed", 2, code_root, env)  # the stand's response stored: every run below is warm
    rows = []
    for periods in counts:
        timed = child("timed", periods, code_root, env)
        traced = child("traced", periods, code_root, env)
        rows.append((periods, timed, traced))
    first_s = rows[0][1]["seconds"]
    first_traced = rows[0][2]["traced_bytes"]
    first_extra = max(rows[0][1]["rss_kib"] - base, 1)
    print(f"code: {code_root}   (baseline RSS after imports {base / 1024:.1f} MiB)")
    print(
        f"{'P':>4} {'stated':>6} {'work':>6} {'est.':>5} {'wall s':>7} {'wall x':>7} "
        f"{'traced MiB':>10} {'traced x':>8} {'RSS MiB':>8} {'extra x':>7}"
    )
    for periods, timed, traced in rows:
        extra = timed["rss_kib"] - base
        print(
            f"{periods:>4} {timed['periods']:>6} {timed['work']['periods']:>6} "
            f"{timed['work']['estimates']:>5} {timed['seconds']:>7.2f} "
            f"{timed['seconds'] / first_s:>7.2f} {traced['traced_bytes'] / 2**20:>10.1f} "
            f"{traced['traced_bytes'] / first_traced:>8.2f} {timed['rss_kib'] / 1024:>8.1f} "
            f"{extra / first_extra:>7.2f}"
        )


def parts() -> None:
    """Print where a live lpm run's memory goes (tracemalloc, this process)."""
    import time
    import tracemalloc

    import numpy as np

    sys.path.insert(0, str(ROOT))
    from dsp.crestfactor import synthesize
    from dsp.lpm_record import BatchedRecord, record_estimate
    from dsp.multisine import preset_plan

    plan = preset_plan("capacitive")
    n = plan.period_samples
    rng = np.random.default_rng(1)
    drive = synthesize(plan.bins, np.ones(len(plan.lines)), plan.phases_rad, n)

    def periods(p: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        u = np.tile(drive, (p, 1)) + 1e-5 * rng.standard_normal((p, n))
        return u, 0.5 * u + 1e-5 * rng.standard_normal((p, n)), np.tile(drive, (p, 1))

    print(f"capacitive plan: {len(plan.lines)} lines, {n} samples per period")
    tracemalloc.start()
    for p in (10, 13, 16):
        u, y, d = periods(p)
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        record_estimate(u, y, plan, drive_blocks=d)
        peak = (tracemalloc.get_traced_memory()[1] - base) / 2**20
        print(f"whole record of {p} periods: peak {peak:.1f} MiB over its inputs")
    u, y, d = periods(16)
    base = tracemalloc.get_traced_memory()[0]
    tracemalloc.reset_peak()
    record = BatchedRecord(64, plan)
    t0 = time.perf_counter()
    for _ in range(4):
        record.add(u, y, d)
    seconds = time.perf_counter() - t0
    held = (tracemalloc.get_traced_memory()[0] - base) / 2**20
    peak = (tracemalloc.get_traced_memory()[1] - base) / 2**20
    print(f"batched record: feeding 16-period batches peak {peak:.1f} MiB, held {held:.1f} MiB")
    tracemalloc.reset_peak()
    record.estimate()
    peak = (tracemalloc.get_traced_memory()[1] - base) / 2**20
    print(f"batched record: its estimate peak {peak:.1f} MiB")
    print(f"feeding 64 periods: {seconds:.2f} s wall (load average {os.getloadavg()[0]:.2f})")


def compare(folder: Path) -> None:
    """Print how far the batched estimate of a stored lpm run's record is from the whole's."""
    import numpy as np

    sys.path.insert(0, str(ROOT))
    from app.procedure.analysis import read_for_analysis
    from dsp.lpm_record import record_estimate, record_estimate_batches

    recording = read_for_analysis(folder)
    p, n = recording.analysed_periods, recording.period_samples
    reference, dut = recording.period_range(0, p)
    start = recording.settle_periods * n
    if recording.drive_v is None:
        raise SystemExit(f"{folder}: no drive recorded")
    drive = np.asarray(recording.drive_v[start : start + p * n]).reshape(p, n)
    whole = record_estimate(reference, dut, recording.plan, drive_blocks=drive)
    cut = ((reference[a : a + 16], dut[a : a + 16], drive[a : a + 16]) for a in range(0, p, 16))
    batched = record_estimate_batches(cut, p, recording.plan)
    a, b = whole.estimate.relative_type_a, batched.estimate.relative_type_a
    differs = np.abs(b / a - 1)
    found = (
        whole.nonlinear and whole.nonlinear.found,
        batched.nonlinear and batched.nonlinear.found,
    )
    print(f"{p} periods; distortion found whole / batched: {found[0]} / {found[1]}")
    print(
        f"type A: batched / whole - 1 at most {np.nanmax(differs):.3g} (median "
        f"{np.nanmedian(differs):.3g}); worst line {np.nanmax(a):.6g} / {np.nanmax(b):.6g}"
    )
    h = np.abs(batched.estimate.response / whole.estimate.response - 1)
    print(f"H: batched / whole - 1 at most {np.nanmax(h):.3g}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("periods", nargs="*", type=int, help="run lengths (default 10 30 60)")
    parser.add_argument("--smoke", action="store_true", help="2 and 3 periods")
    parser.add_argument("--also", type=Path, help="another checkout to measure the same way")
    parser.add_argument("--only-also", action="store_true", help="measure --also's code only")
    parser.add_argument("--parts", action="store_true", help="where the memory goes")
    parser.add_argument("--compare", type=Path, help="a run folder: batched against whole")
    args = parser.parse_args(argv)
    if args.parts:
        parts()
        return 0
    if args.compare is not None:
        compare(args.compare)
        return 0
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    counts = [2, 3] if args.smoke else (args.periods or [10, 30, 60])
    if any(p < 2 for p in counts):
        parser.error("periods: each at least 2")
    with tempfile.TemporaryDirectory() as data:
        env = {**os.environ, "ACCELCAL_DATA_DIR": data}
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        print(f"load average {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f}")
        roots = [*([] if args.only_also else [ROOT]), *([args.also] if args.also else [])]
        if not roots:
            parser.error("--only-also: give --also PATH")
        for root in roots:
            measure(root.resolve(), counts, env)
        print(f"load average {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
