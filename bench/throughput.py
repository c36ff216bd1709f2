"""The laboratory's throughput, not only the sweep's (issue 36 point 7): sensors per hour when
one DUT is calibrated at a time against four at a time on the four-position fixture, and for a
triaxial sensor three separate runs against one guided session of three orientations.

What is measured (wall time of the real commands, on the simulated stand in real time
(--paced), warm after a first run that stores the stand's response; each a fresh interpreter):

    one at a time:  accelcal run --sim --dut piezo --dut-id SN-k      then
                    accelcal certificate RUN ...                       (per sensor)
    four at a time: accelcal run --stand sim/stand-fixture4.toml --dut A=SN-1 ... --dut D=SN-4
                    then accelcal certificate --batch BATCH ...        (per run of four)

What is modelled (the technician's hands; stated, changeable by option, printed with the
figures). The Modal Shop publishes 5 minutes per axis on its comparison system: 60 % mounting
and handling (180 s), 30 % sweep, 10 % data entry (30 s). The 180 s of handling is split here
into what is done once per run at the exciter (--per-run-s, default 120 s: open the guard, take
the last DUT or fixture off, mount the next on the armature with its torque, route the cables,
close) and what is done per sensor (--per-sensor-s, default 60 s: unpack, inspect, fit the
stud, connect its cable; on the fixture, at the bench). Data entry per sensor: --entry-s
(default 30 s, typed, the same in both cases). A certificate's own command is measured.

A day's batch (--sensors, default 20) takes: one at a time, per sensor: per-run + per-sensor +
entry + run + certificate; four at a time, per run of four: per-run + 4 x (per-sensor + entry)
+ run + the four certificates. Sensors per hour = sensors / time. The ratio depends on the
split of handling, so the script also prints it over a range of splits (the same 180 s).

Triaxial: three runs today means three times the one-at-a-time cost of a sensor (three
mountings at the exciter, three entries, three certificates); one guided session means three
remounts of the cube or the sensor (--remount-s, default 60 s each: the sensor stays cabled,
only turned), one entry, three runs of the sensor's three channels, one certificate. The run
of three channels is measured as a run of three DUTs on the fixture stand (the same
acquisition and estimation per channel); the certificate's time as one member's.

Run:   python bench/throughput.py [--sensors 20] [--repeats 3]
Smoke: python bench/throughput.py --smoke
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FIXTURE_STAND = ROOT / "sim" / "stand-fixture4.toml"
POSITIONS = ("A", "B", "C", "D")
CERTIFICATE_ITEMS = [
    "--customer", "ACME Ltd", "--customer-address", "1 Test Street, 00-001 Testtown",
    "--authorised-by", "J. Smith", "--temperature", "23", "--mounting", "stud",
]  # fmt: skip
HANDLING_S = 180.0  # The Modal Shop: 60 % of 5 minutes per axis
log = logging.getLogger("bench.throughput")


@dataclass(frozen=True)
class Handling:
    """The technician's stated times (s)."""

    per_run_s: float
    per_sensor_s: float
    entry_s: float
    remount_s: float


@dataclass(frozen=True)
class Measured:
    """Median wall times (s) of the commands."""

    single_run_s: float
    single_certificate_s: float
    batch_run_s: float  # four DUTs
    batch_certificates_s: float  # the four certificates of one batch
    triple_run_s: float  # three DUT channels


def accelcal(args: list[str], cwd: Path, env: dict[str, str]) -> tuple[float, str]:
    """Run one command in a fresh interpreter; its wall time (s) and stdout."""
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "app", *args], cwd=cwd, env=env, capture_output=True, text=True
    )
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"accelcal {' '.join(args)} failed ({done.returncode}):\n{done.stderr}")
    return wall, done.stdout


def newest_run(runs: Path, before: set[str]) -> Path:
    (new,) = [p for p in runs.iterdir() if p.name not in before and p.is_dir()]
    return new


def measure(work: Path, repeats: int, periods: list[str]) -> Measured:
    """The commands' median wall times over `repeats` (after one warm-up of each stand)."""
    env = dict(os.environ, ACCELCAL_DATA_DIR=str(work / "data"), PYTHONPATH=str(ROOT))
    runs = work / "runs"
    runs.mkdir()
    single, single_cert, batch, batch_cert, triple = [], [], [], [], []
    serial = 0
    for attempt in range(repeats + 1):  # the first of each: stores the stand's response
        serial += 1
        before = {p.name for p in runs.iterdir()}
        wall, _ = accelcal(
            ["run", "--sim", "--dut", "piezo", "--dut-id", f"SN-{serial}", "--out", str(runs),
             *periods], work, env,
        )  # fmt: skip
        run = newest_run(runs, before)
        cert, _ = accelcal(
            ["certificate", str(run), *CERTIFICATE_ITEMS, "--certificate-number", f"C-{serial}"],
            work, env,
        )  # fmt: skip
        duts: list[str] = []
        for position in POSITIONS:
            serial += 1
            duts += ["--dut", f"{position}=SN-{serial}"]
        before = {p.name for p in runs.iterdir()}
        batch_wall, _ = accelcal(
            ["run", "--stand", str(FIXTURE_STAND), *duts, "--out", str(runs), *periods], work, env
        )
        new = [p for p in runs.iterdir() if p.name not in before and (p / "batch.json").exists()]
        batch_id = json.loads((new[0] / "batch.json").read_text())["batch_id"]
        batch_cert_wall, _ = accelcal(
            ["certificate", "--batch", batch_id, *CERTIFICATE_ITEMS], work, env
        )
        triple_wall, _ = accelcal(
            ["run", "--stand", str(FIXTURE_STAND), *duts[:6], "--out", str(runs), *periods],
            work, env,
        )  # fmt: skip
        if attempt == 0:
            continue
        single.append(wall)
        single_cert.append(cert)
        batch.append(batch_wall)
        batch_cert.append(batch_cert_wall)
        triple.append(triple_wall)
    med = statistics.median
    return Measured(med(single), med(single_cert), med(batch), med(batch_cert), med(triple))


def per_hour(sensors: int, seconds: float) -> float:
    return 3600.0 * sensors / seconds


def one_at_a_time_s(sensors: int, h: Handling, m: Measured) -> float:
    return sensors * (
        h.per_run_s + h.per_sensor_s + h.entry_s + m.single_run_s + m.single_certificate_s
    )


def four_at_a_time_s(sensors: int, h: Handling, m: Measured) -> float:
    runs = -(-sensors // 4)
    return runs * (h.per_run_s + m.batch_run_s + m.batch_certificates_s) + sensors * (
        h.per_sensor_s + h.entry_s
    )


def triaxial_three_runs_s(h: Handling, m: Measured) -> float:
    return one_at_a_time_s(3, h, m)


def triaxial_guided_s(h: Handling, m: Measured) -> float:
    """One mounting at the exciter, three turns of the sensor, one entry, three runs of three
    channels, one certificate (a member's)."""
    return (
        h.per_run_s + h.per_sensor_s + 2 * h.remount_s + h.entry_s
        + 3 * m.triple_run_s + m.batch_certificates_s / 4
    )  # fmt: skip


def report(sensors: int, h: Handling, m: Measured) -> None:
    one = one_at_a_time_s(sensors, h, m)
    four = four_at_a_time_s(sensors, h, m)
    print(
        f"measured (median wall, s): one DUT's run {m.single_run_s:.1f}, its certificate "
        f"{m.single_certificate_s:.1f}; four DUTs' run {m.batch_run_s:.1f}, their four "
        f"certificates {m.batch_certificates_s:.1f}; three channels' run {m.triple_run_s:.1f}"
    )
    print(
        f"handling (stated, s): per run at the exciter {h.per_run_s:g}, per sensor "
        f"{h.per_sensor_s:g}, data entry per sensor {h.entry_s:g}, triaxial remount {h.remount_s:g}"
    )
    print("| a day's batch | time | sensors per hour | ratio |")
    print("| --- | --- | --- | --- |")
    print(
        f"| {sensors} sensors one at a time | {one / 60:.1f} min | "
        f"{per_hour(sensors, one):.1f} | 1.00x |"
    )
    print(
        f"| {sensors} sensors four at a time | {four / 60:.1f} min | "
        f"{per_hour(sensors, four):.1f} | {one / four:.2f}x |"
    )
    three, guided = triaxial_three_runs_s(h, m), triaxial_guided_s(h, m)
    print(
        f"| a triaxial sensor, three runs | {three / 60:.1f} min | "
        f"{per_hour(1, three):.1f} | 1.00x |"
    )
    print(
        f"| a triaxial sensor, one guided session | {guided / 60:.1f} min | "
        f"{per_hour(1, guided):.1f} | {three / guided:.2f}x |"
    )
    print(
        f"four at a time against one at a time, the {HANDLING_S:g} s of handling split otherwise:"
    )
    print("| per run at the exciter | per sensor | ratio |")
    print("| --- | --- | --- |")
    for per_run in (60.0, 90.0, 120.0, 150.0, 170.0):
        split = Handling(per_run, HANDLING_S - per_run, h.entry_s, h.remount_s)
        ratio = one_at_a_time_s(sensors, split, m) / four_at_a_time_s(sensors, split, m)
        print(f"| {per_run:g} s | {HANDLING_S - per_run:g} s | {ratio:.2f}x |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sensors", type=int, default=20, help="a day's batch (sensors)")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs of each command")
    parser.add_argument("--per-run-s", type=float, default=120.0)
    parser.add_argument("--per-sensor-s", type=float, default=60.0)
    parser.add_argument("--entry-s", type=float, default=30.0)
    parser.add_argument("--remount-s", type=float, default=60.0)
    parser.add_argument("--smoke", action="store_true", help="one repeat, short runs (CI)")
    args = parser.parse_args()
    if args.sensors < 1 or args.repeats < 1:
        parser.error("--sensors and --repeats: at least 1")
    logging.basicConfig(level=logging.WARNING)
    repeats = 1 if args.smoke else args.repeats
    # the simulated stand in real time (the shaker's own seconds), unpaced in the smoke run
    periods = ["--technician", "A. Tech"] + ([] if args.smoke else ["--paced"])
    load = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="accelcal-throughput-") as tmp:
        measured = measure(Path(tmp), repeats, periods)
    handling = Handling(args.per_run_s, args.per_sensor_s, args.entry_s, args.remount_s)
    print(f"load average at start {load[0]:.2f}, {load[1]:.2f}, {load[2]:.2f}; {repeats} repeats")
    report(args.sensors, handling, measured)


if __name__ == "__main__":
    main()
