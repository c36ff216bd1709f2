"""Import speed and memory: the same recording read from CSV, TDMS and HDF5 (issue 16 point 7).

Recording: 51.2 kS/s x 2 channels x 30 s (30 periods of 51 200 samples, ISO 266 lines
10 Hz-20 kHz, the synthetic low-pass DUT of tests/synthetic.py with noise on both channels).
The CSV holds each sample as Python's shortest round-trip repr ("reference_v,dut_v" header);
a second CSV is numpy.savetxt's '%.18e' (wider numbers). The TDMS file is written with
npTDMS's writer, one segment per period. Each reader runs in a fresh process (best time of
`--repeats`): the time of the reader (read + validate, app.io.hdf5 / app.io.tdms), its growth
of the resident set (VmHWM after, reset by /proc/self/clear_refs, less VmRSS before; catches
what the HDF5 library allocates) and, in a run of its own, its peak traced memory
(tracemalloc: numpy buffers and Python objects), both as multiples of the float64 data
(2 x 1 536 000 x 8 B = 24.6 MB); and the whole `accelcal analyze` command. Times are printed
as ratios to the HDF5 path measured in the same run.

Goal: CSV at most 1.5x the HDF5 path's time and at most 2x the data's memory.

Run: python bench/import.py [--repeats 3] [--seconds 30] [--smoke]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.io.csv import read_csv  # noqa: E402
from app.io.hdf5 import read_recording, write_recording  # noqa: E402
from dsp import iso266  # noqa: E402
from dsp.calibration import ReferenceChain  # noqa: E402
from dsp.multisine import Plan, make_plan  # noqa: E402
from dsp.uncertainty import Budget  # noqa: E402
from tests.synthetic import (  # noqa: E402
    lowpass_response,
    make_recording,
    write_csv,
    write_tdms,
)

FS = 51_200.0
N = 51_200
LINES = iso266.nominal_frequencies(10, 20_000)


def make_files(folder: Path, seconds: int) -> dict[str, Path]:
    """The recording as rec.h5, rec.csv, rec-savetxt.csv, rec.tdms (+ plan.json)."""
    plan = make_plan(LINES, FS, N, 5.0, 160.0, phases_rad=[0.0] * len(LINES))
    rec = make_recording(
        plan,
        lowpass_response(),
        periods=int(seconds * FS / N),
        reference_noise_v=1e-4,
        dut_noise_v=1e-3,
    )
    files = {
        "hdf5": folder / "rec.h5",
        "csv": folder / "rec.csv",
        "csv-savetxt": folder / "rec-savetxt.csv",
        "tdms": folder / "rec.tdms",
    }
    write_recording(files["hdf5"], rec)
    write_csv(files["csv"], rec)
    np.savetxt(
        files["csv-savetxt"],
        np.column_stack([rec.reference_v, rec.dut_v]),
        delimiter=",",
        header="reference_v,dut_v",
        comments="",
    )
    write_tdms(files["tdms"], rec)
    (folder / "plan.json").write_text(json.dumps(plan.to_dict()))
    return files


def read(kind: str, path: Path, plan: Plan):
    """The reader of `kind` on `path`: a Recording."""
    chain, budget = ReferenceChain.flat(1.0, skew_s=0.0), Budget(())
    if kind == "hdf5":
        return read_recording(path)
    if kind.startswith("csv"):
        return read_csv(path, plan, chain, budget)
    from app.io.tdms import read_tdms

    return read_tdms(path, plan, chain, budget, reference="reference", dut="dut")


def measure(kind: str, path: Path, traced: bool) -> dict[str, float]:
    """Child process: time and max-RSS growth of one read (s, bytes), or with `traced` its
    traced peak (tracemalloc slows Python objects down, so it is a run of its own)."""
    plan = Plan.from_dict(json.loads((path.parent / "plan.json").read_text()))
    rss0 = _reset_peak()
    if traced:
        tracemalloc.start()
    t0 = time.perf_counter()
    rec = read(kind, path, plan)
    elapsed = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    rss = _peak_bytes() - rss0
    data = 8 * (rec.reference_v.size + rec.dut_v.size)
    return {"time_s": elapsed, "traced": peak, "rss": rss, "data": data}


def _status_bytes(key: str) -> int | None:
    """A /proc/self/status figure in bytes (VmRSS, VmHWM; Linux), None without it."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(key + ":"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def _reset_peak() -> int:
    """Reset the resident-set peak (VmHWM) to now, where Linux allows it; the resident set
    now, bytes (0 when unknown: the growth printed is then the process's whole peak)."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        return 0
    return _status_bytes("VmRSS") or 0


def _peak_bytes() -> int:
    """The resident-set peak (VmHWM, else ru_maxrss), bytes."""
    hwm = _status_bytes("VmHWM")
    return hwm if hwm is not None else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def child(kind: str, path: Path, traced: bool = False) -> dict[str, float]:
    argv = [sys.executable, __file__, "--measure", kind, str(path)]
    out = subprocess.run(
        [*argv, "--traced"] if traced else argv, check=True, capture_output=True, text=True
    ).stdout
    return json.loads(out)


def analyze_time(kind: str, path: Path) -> float:
    """Wall time of the whole `accelcal analyze` command on `path`, s."""
    argv = [sys.executable, "-m", "app", "analyze", str(path), "--json"]
    freqs = ",".join(f"{f:g}" for f in LINES)
    plan = ["--frequencies", freqs, "--period", str(N), "--reference-sensitivity", "1"]
    if kind.startswith("csv"):
        argv += [*plan, "--sample-rate", f"{FS:g}", "--skew", "0"]
    elif kind == "tdms":
        argv += [*plan, "--reference", "reference", "--dut", "dut", "--skew", "0"]
    t0 = time.perf_counter()
    subprocess.run(argv, check=True, capture_output=True, cwd=ROOT)
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=int, default=30)
    parser.add_argument("--measure", nargs=2, metavar=("KIND", "FILE"), help=argparse.SUPPRESS)
    parser.add_argument("--traced", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--kinds", default="hdf5,csv,csv-savetxt,tdms")
    parser.add_argument("--smoke", action="store_true", help="2 s, one repeat: runs?")
    args = parser.parse_args(argv)
    if args.smoke:
        args.seconds, args.repeats, args.kinds = 2, 1, "hdf5,csv"
    if args.measure:
        print(json.dumps(measure(args.measure[0], Path(args.measure[1]), args.traced)))
        return 0
    kinds = args.kinds.split(",")
    with tempfile.TemporaryDirectory() as tmp:
        files = make_files(Path(tmp), args.seconds)
        best: dict[str, dict[str, float]] = {}
        whole: dict[str, float] = {}
        for _ in range(args.repeats):  # interleaved, so a load change hits every format
            for kind in kinds:
                got = child(kind, files[kind])
                prev = best.get(kind)
                if prev is None or got["time_s"] < prev["time_s"]:
                    best[kind] = got
                whole[kind] = min(whole.get(kind, np.inf), analyze_time(kind, files[kind]))
        for kind in kinds:
            best[kind]["traced"] = child(kind, files[kind], traced=True)["traced"]
        sizes = {kind: files[kind].stat().st_size / 1e6 for kind in kinds}
    base, base_whole = best["hdf5"]["time_s"], whole["hdf5"]
    print(
        f"{args.seconds} s, 2 x {FS / 1e3:g} kS/s, data {best['hdf5']['data'] / 1e6:.1f} MB "
        f"float64; best of {args.repeats}"
    )
    print(
        "| format | file MB | read s | read / HDF5 | traced peak / data | max RSS growth / data"
        " | analyze s | analyze / HDF5 |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for kind in kinds:
        b = best[kind]
        print(
            f"| {kind} | {sizes[kind]:.1f} | {b['time_s']:.3f} | {b['time_s'] / base:.2f} | "
            f"{b['traced'] / b['data']:.2f} | {b['rss'] / b['data']:.2f} | {whole[kind]:.2f} | "
            f"{whole[kind] / base_whole:.2f} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
