"""How long the run worker's heavy calls keep another thread from the GIL (issue 34 point 6).

Each call the GUI bench's run makes at 51.2 kS/s with 2 s periods (the piezo preset's lines)
runs on this thread while a probe thread sleeps 0.2 ms at a time and notes the longest gap
between its turns: a call that holds the GIL for X ms gives a gap of at least X ms in every
repetition, a call that releases it (numpy's FFTs and ufuncs do) gives gaps of the scheduler's
and the switch interval's size only. The figure per call is the smallest of REPEATS longest
gaps (a load adds gaps to some repetitions, not to all), next to the call's own median time.
The Qt window's thread needs the GIL at every Python callback, so a call that holds it longer
than the 50 ms target stalls the window whatever else is done. A second figure: the time a
thread takes for ROUND_TRIPS GIL round trips while another runs Python, per switch interval
(the convoy: each round trip waits up to one interval; app.gui.worker.GIL_SWITCH_S).

Run: python bench/gil_holds.py [--repeats 5] [--switch-ms 5] [--smoke]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.procedure.planning import PlanRequest, build_plan
from app.procedure.preflight import fade_in_for, motion_peaks
from app.stand.config import load
from dsp import nonlinear
from dsp.crestfactor import peak_grid_samples, synthesize
from dsp.fades import fade_motion

FS, N = 51_200.0, 102_400  # the GUI bench's plan: 2 s periods at 51.2 kS/s


def longest_wait_ms(call: Callable[[], object], repeats: int) -> tuple[float, float, float]:
    """(the smallest over `repeats` of the probe's longest gap, the calling thread's CPU time
    within that gap, the call's median time), ms. The CPU time is what the call computed while
    the probe waited: a load stretches the gap, not that."""
    gaps: list[tuple[float, float]] = []
    times = []
    clock = time.pthread_getcpuclockid(threading.get_ident())
    for _ in range(repeats):
        seen: list[tuple[float, float]] = []
        done = threading.Event()

        def probe(seen: list[tuple[float, float]] = seen, done: threading.Event = done) -> None:
            last, last_cpu = time.perf_counter(), time.clock_gettime(clock)
            while not done.is_set():
                time.sleep(0.0002)
                now, cpu = time.perf_counter(), time.clock_gettime(clock)
                seen.append((now - last, cpu - last_cpu))
                last, last_cpu = now, cpu

        thread = threading.Thread(target=probe)
        thread.start()
        time.sleep(0.005)
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
        done.set()
        thread.join()
        gaps.append(max(seen))
    gap, cpu = min(gaps)
    return 1e3 * gap, 1e3 * cpu, 1e3 * statistics.median(times)


ROUND_TRIPS = 10  # GIL round trips per measurement: a frame's Python callbacks, about


def round_trips_ms(switch_s: float, repeats: int) -> float:
    """The median time (ms) one thread takes for ROUND_TRIPS GIL round trips (release and take
    it back, as the window's thread does at each Python callback Qt makes) while another thread
    runs Python bytecode (as the run worker does between numpy calls), at the switch interval
    `switch_s`: the waiting thread takes the GIL back only when the holder is asked to drop it,
    after the interval. Restores the interval it found."""
    before = sys.getswitchinterval()
    sys.setswitchinterval(switch_s)
    stop = threading.Event()

    def busy() -> None:
        total = 0
        while not stop.is_set():
            for i in range(1000):
                total += i

    worker = threading.Thread(target=busy)
    worker.start()
    try:
        time.sleep(0.02)
        took = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            for _ in range(ROUND_TRIPS):
                time.sleep(0)  # releases the GIL and takes it back
            took.append(time.perf_counter() - t0)
    finally:
        stop.set()
        worker.join()
        sys.setswitchinterval(before)
    return 1e3 * statistics.median(took)


def calls() -> dict[str, Callable[[], object]]:
    """The worker's heavy calls on the GUI bench's plan, by what they are."""
    plan = build_plan(PlanRequest(preset="piezo", sample_rate_hz=FS, period_samples=N))
    limits = load().limits
    target = plan.amplitudes_ms2 * np.exp(1j * (plan.phases_rad - np.pi / 2))
    grid = peak_grid_samples(plan.period_samples, plan.bins)
    rng = np.random.default_rng(1)
    reference = synthesize(plan.bins, np.full(len(plan.bins), 0.01), plan.phases_rad, N)
    reference = reference + 1e-5 * rng.standard_normal(N)
    dut = 0.5 * reference + 0.02 * reference**3 + 1e-5 * rng.standard_normal(N)
    u_spec, y_spec = (np.fft.rfft(x) * (2.0 / N) for x in (reference, dut))
    lines = np.asarray(plan.bins)
    mains = [round(50.0 * k * N / FS) for k in range(1, 40)]
    return {
        f"synthesize on the peak grid ({grid} points, one irfft)": lambda: synthesize(
            plan.bins, plan.amplitudes_ms2, plan.phases_rad, grid
        ),
        "dsp.fades.fade_motion (fade-in and fade-out)": lambda: fade_motion(
            plan.frequencies_hz, target, 1.0 / plan.frequencies_hz.min(), 0.15
        ),
        "preflight.motion_peaks (3 syntheses and the fades)": lambda: motion_peaks(plan, target),
        "preflight.fade_in_for": lambda: fade_in_for(plan, target, limits),
        "dsp.nonlinear.free_bins (51 201 bins)": lambda: nonlinear.free_bins(
            N // 2 + 1, lines, mains
        ),
        "dsp.nonlinear.estimate (one 2 s record)": lambda: nonlinear.estimate(
            y_spec,
            u_spec,
            lines,
            u_spec[lines],
            y_spec[lines] / u_spec[lines],
            reference,
            excluded_bins=mains,
        ),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="repetitions per call")
    parser.add_argument(
        "--switch-ms", type=float, default=5.0, help="the GIL switch interval (ms; CPython's 5)"
    )
    parser.add_argument("--smoke", action="store_true", help="one repetition (CI)")
    args = parser.parse_args(argv)
    if args.smoke:
        args.repeats = 1
    if args.repeats < 1:
        parser.error("--repeats: must be at least 1")
    if not 0.01 <= args.switch_ms <= 100:
        parser.error("--switch-ms: must be within 0.01 .. 100 ms")
    sys.setswitchinterval(1e-3 * args.switch_ms)
    one, five, fifteen = os.getloadavg()
    print(
        f"GIL switch interval {args.switch_ms:g} ms; {args.repeats} repetitions; load average "
        f"{one:.2f}, {five:.2f}, {fifteen:.2f}; {os.cpu_count()} cores"
    )
    print(
        "| call | its time (median) | longest wait of another thread (smallest of the "
        "repeats) | the call's CPU within that wait |"
    )
    print("| --- | --- | --- | --- |")
    for name, call in calls().items():
        call()  # warm
        wait, cpu, took = longest_wait_ms(call, args.repeats)
        print(f"| {name} | {took:.1f} ms | {wait:.1f} ms | {cpu:.1f} ms |")
    print()
    print(
        f"{ROUND_TRIPS} GIL round trips of one thread while another runs Python (the window's "
        "callbacks against a computing run worker), median:"
    )
    for switch_ms in (5.0, 1.0, 0.5):
        took = round_trips_ms(1e-3 * switch_ms, max(3, args.repeats))
        print(f"- switch interval {switch_ms:g} ms: {took:.1f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
