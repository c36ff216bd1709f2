"""What reading the stand's environment sensor adds to a run's start (issue 35 point 2): the
simulated Fluke 1620A (sim/environment.yaml through pyvisa-sim) read by
app.stand.open.read_environment, as the run does it before config.json is written.

Per repetition, in a fresh interpreter: the amplifiers' simulated resource manager first (as
the simulated stand opens it: pyvisa and pyvisa-sim imported), then the first read (the
sensor's definitions parsed, its library made: what the sensor adds to a run) and a warm
read; the baseline is `stand_config.load()` of the same stand (what every run already does),
measured in the same run. Prints medians in ms, their ratios to the baseline and the load
average (wall times are load-dependent: the lead re-measures at idle).

Run: python bench/environment_read.py [--runs 11]
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import statistics
import subprocess
import sys

CHILD = r"""
import json, time
t0 = time.perf_counter()
from app.stand import config as stand_config
config = stand_config.load(None)
t1 = time.perf_counter()
from sim.visa import simulated_resource_manager
simulated_resource_manager()  # what the simulated stand's amplifiers already cost a run
t2 = time.perf_counter()
from app.stand.open import read_environment
first = read_environment(config, "now")
t3 = time.perf_counter()
again = read_environment(config, "now")
t4 = time.perf_counter()
assert first is not None and again is not None, "the simulated sensor was not read"
print(json.dumps({"load": t1 - t0, "amplifiers": t2 - t1, "first": t3 - t2, "warm": t4 - t3}))
"""

log = logging.getLogger("bench.environment_read")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=11, help="fresh interpreters (median)")
    parser.add_argument("--smoke", action="store_true", help="one interpreter (CI)")
    args = parser.parse_args()
    if args.smoke:
        args.runs = 1
    if args.runs < 1:
        parser.error("--runs: must be at least 1")
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    samples: dict[str, list[float]] = {"load": [], "amplifiers": [], "first": [], "warm": []}
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    for _ in range(args.runs):
        out = subprocess.run(
            [sys.executable, "-c", CHILD], capture_output=True, text=True, check=True, env=env
        ).stdout
        for key, value in json.loads(out.strip().splitlines()[-1]).items():
            samples[key].append(value)
    median = {key: statistics.median(values) * 1e3 for key, values in samples.items()}
    base = median["load"]
    log.info("load average: %s", " ".join(f"{x:.2f}" for x in os.getloadavg()))
    log.info("runs: %d fresh interpreters, medians", args.runs)
    log.info("stand_config.load() (baseline):      %7.1f ms  1.00x", base)
    log.info(
        "amplifiers' pyvisa-sim manager:      %7.1f ms  %.2fx",
        median["amplifiers"],
        median["amplifiers"] / base,
    )
    log.info(
        "read_environment, first in process:  %7.1f ms  %.2fx",
        median["first"],
        median["first"] / base,
    )
    log.info(
        "read_environment, again:             %7.1f ms  %.2fx",
        median["warm"],
        median["warm"] / base,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
