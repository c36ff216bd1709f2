"""`accelcal analyze` peak memory against the record's length (issue 34 point 4).

Two recordings of the same plan are made with the simulated stand (`accelcal simulate --dut
piezo`, 10 and 300 periods after settling), then each is analysed by `accelcal analyze` in a
fresh process per estimator (the default, periodic and lpm), and that process reports its peak
resident memory (getrusage ru_maxrss) and, in another fresh process, the peak memory traced by
tracemalloc (what Python and numpy allocate, without the interpreter and libraries). A fresh
process that only imports what `analyze` imports gives the baseline RSS; "extra" is the peak
minus it. Memory does not depend on the machine's load: these figures are exact to a few
hundred kB.

Acceptance (issue 34): peak RSS of the 300-period analysis at most 1.3x the 10-period one for
the default estimator and for periodic. Exit status 1 when one of those two exceeds it.

Run: python bench/analyze_memory.py [SHORT LONG]   (default 10 300 periods)
Smoke (CI): python bench/analyze_memory.py --smoke   (8 and 16 periods, not judged)
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from dsp.estimators import DEFAULT_ESTIMATOR  # noqa: E402

LIMIT = 1.3  # issue 34: peak memory 300 vs 10 periods
DUT = "piezo"

CHILD = r"""
import json, os, resource, sys, tracemalloc
traced = sys.argv[1] == "traced"
path, estimator = sys.argv[2], sys.argv[3]
from app.cli import main
from app.procedure import analysis  # noqa: F401  (what analyze imports, for the baseline)
if path == "-":
    code = 0
    peak = 0
else:
    if traced:
        tracemalloc.start()
    devnull = open(os.devnull, "w")
    stdout, sys.stdout = sys.stdout, devnull
    code = main(["analyze", path, "--estimator", estimator, "--json"])
    sys.stdout = stdout
    peak = tracemalloc.get_traced_memory()[1] if traced else 0
rss_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"code": code, "rss_kib": rss_kib, "traced_bytes": peak}))
"""


def child(mode: str, path: str, estimator: str, env: dict[str, str]) -> dict:
    """One fresh interpreter: `accelcal analyze` of `path` (or nothing: "-"), its peak memory."""
    out = subprocess.run(
        [sys.executable, "-c", CHILD, mode, path, estimator],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
        check=False,
    )
    if out.returncode != 0:
        raise SystemExit(f"analyze child failed ({out.returncode}): {out.stderr.strip()[-400:]}")
    result = json.loads(out.stdout.strip().splitlines()[-1])
    if result["code"] != 0:
        raise SystemExit(f"accelcal analyze {path} --estimator {estimator}: exit {result['code']}")
    return result


def simulate(periods: int, path: Path, env: dict[str, str]) -> None:
    command = ["simulate", "--dut", DUT, "--periods", str(periods), "--out", str(path)]
    subprocess.run(
        [sys.executable, "-m", "app", *command],
        check=True,
        capture_output=True,
        env=env,
        cwd=ROOT,
    )


def main(argv: list[str]) -> int:
    smoke = argv[1:] == ["--smoke"]
    try:
        short, long = (int(a) for a in argv[1:3]) if len(argv) >= 3 else (10, 300)
    except ValueError:
        print(f"usage: {Path(argv[0]).name} [SHORT LONG] | --smoke", file=sys.stderr)
        return 2
    if smoke:
        short, long = 8, 16
    estimators = list(dict.fromkeys([DEFAULT_ESTIMATOR, "periodic", "lpm"]))
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "ACCELCAL_DATA_DIR": str(Path(tmp) / "data")}
        files = {}
        for periods in (short, long):
            files[periods] = Path(tmp) / f"{DUT}-{periods}.h5"
            simulate(periods, files[periods], env)
        base = child("rss", "-", "periodic", env)["rss_kib"]
        print(
            f"analyze memory: {DUT}, {short} and {long} periods "
            f"({files[short].stat().st_size / 2**20:.1f} and "
            f"{files[long].stat().st_size / 2**20:.1f} MiB recordings); baseline RSS (imports "
            f"only) {base / 1024:.1f} MiB"
        )
        print(
            "| estimator | periods | peak RSS | extra over baseline | traced peak (tracemalloc) |"
        )
        print("| --- | --- | --- | --- | --- |")
        ratios = {}
        for estimator in estimators:
            row = {}
            for periods in (short, long):
                rss = child("rss", str(files[periods]), estimator, env)["rss_kib"]
                traced = child("traced", str(files[periods]), estimator, env)["traced_bytes"]
                row[periods] = (rss, traced)
                label = estimator + (" (default)" if estimator == DEFAULT_ESTIMATOR else "")
                print(
                    f"| {label} | {periods} | {rss / 1024:.1f} MiB | {(rss - base) / 1024:.1f} "
                    f"MiB | {traced / 2**20:.1f} MiB |"
                )
            ratios[estimator] = (
                row[long][0] / row[short][0],
                row[long][1] / row[short][1],
            )
    failed = False
    for estimator, (rss_ratio, traced_ratio) in ratios.items():
        judged = estimator in (DEFAULT_ESTIMATOR, "periodic")
        verdict = ("ok" if rss_ratio <= LIMIT else "OVER") if judged else "not judged"
        failed |= judged and rss_ratio > LIMIT
        print(
            f"{estimator}: peak RSS {long} / {short} periods = {rss_ratio:.2f} (limit {LIMIT}: "
            f"{verdict}); traced peak ratio {traced_ratio:.2f}"
        )
    return 1 if failed and not smoke else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
