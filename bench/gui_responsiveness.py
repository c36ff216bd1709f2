"""GUI responsiveness during a live run at 2 x 51.2 kS/s (SPEC.md s.11-12, issue 6).

A stand-in procedure on the real run worker (`app.gui.worker.RunWorker`, a plain thread that
queues copies of events for the window's 25 Hz timer) emits, every 50 ms, the events of one
period of a 51.2 kS/s plan with 50 ms periods (2 channels x 2560 samples, a live estimate of
34 lines), the fastest stream the GUI can meet. Measured on the GUI thread: the longest stall
(a 2 ms heartbeat timer's largest gap beyond its interval) and the plot updates per second.
Targets: stall < 50 ms, >= 20 updates per second. The heartbeat's own gap with an idle window,
measured first in the same run, is the baseline.

Run: QT_QPA_PLATFORM=offscreen python bench/gui_responsiveness.py [--smoke]
"""

from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication

from app.gui.main_window import MainWindow
from app.gui.worker import RunWorker
from app.io.vocabulary import RunStatus
from app.procedure import Finished, PeriodBlock, PeriodEstimate, State
from dsp import iso266
from dsp.calibration import ReferenceChain, compute_results
from dsp.multisine import make_plan
from dsp.spectral import SpectralAccumulator
from dsp.uncertainty import Budget

FS, N = 51_200.0, 2560
SMOKE = "--smoke" in sys.argv[1:]  # 1 s of live run: checks it still runs
SECONDS = 1.0 if SMOKE else 6.0


class FeedingProcedure:
    """Plays a procedure's part for the worker: emits period and estimate events until
    stopped."""

    def __init__(self, plan) -> None:
        self.plan = plan
        self.listener = None
        self.stop = threading.Event()

    def abort(self, reason: str = "") -> None:
        self.stop.set()

    emergency_stop = abort

    def run(self) -> Finished:
        plan, emit = self.plan, self.listener
        rng = np.random.default_rng(0)
        i = np.arange(N)
        u0 = sum(np.sin(2 * np.pi * m * i / N + 0.3 * k) for k, m in enumerate(plan.bins)) * 0.02
        acc = SpectralAccumulator(N, plan.bins)
        chain = ReferenceChain.flat(1.0)
        k = 0
        while not self.stop.is_set():
            t0 = time.perf_counter()
            noise = 1e-4 * rng.standard_normal((2, N))
            block = np.vstack([u0, 0.5 * u0]) + noise
            acc.add_period(block[0], block[1])
            k += 1
            emit(PeriodBlock(k, State.ACQUIRING, ("reference", "dut"), block, u0))
            if k >= 2:
                estimate = acc.estimate()
                results = compute_results(estimate, plan, chain, Budget(()))
                emit(PeriodEstimate(k, estimate, results))
            time.sleep(max(0.0, N / FS - (time.perf_counter() - t0)))
        return Finished(RunStatus.ABORTED, "bench over", None, {})


class NoStand:
    def close(self) -> None:
        pass


def main() -> None:
    app = QApplication(sys.argv[:1])
    window = MainWindow(out=Path("/tmp/bench-gui-runs"), paced=False)
    window.resize(1400, 900)
    window.show()
    freqs = [f for f in iso266.nominal_frequencies(20, 20_000) if round(f * N / FS) * FS / N == f]
    plan = make_plan(freqs, FS, N, 5.0, freqs[len(freqs) // 2], phases_rad=np.zeros(len(freqs)))
    renders = {"count": 0}
    original = window._draw

    def counted() -> None:
        original()
        renders["count"] += 1

    window._draw = counted
    gaps: list[float] = []
    last = {"t": time.perf_counter()}

    def beat() -> None:
        now = time.perf_counter()
        gaps.append(now - last["t"])
        last["t"] = now

    heartbeat = QTimer(interval=2, timeout=beat)
    heartbeat.start()

    def phase(seconds: float) -> None:
        end = time.perf_counter() + seconds
        while time.perf_counter() < end:
            app.processEvents()
            time.sleep(0.001)

    phase(1.0)
    idle = max(gaps) * 1e3 - 2
    gaps.clear()
    procedure = FeedingProcedure(plan)
    window._live = {"plan": plan}
    window.worker = RunWorker(procedure, NoStand())
    renders["count"] = 0
    window.worker.start()
    phase(SECONDS)
    procedure.abort()
    window.worker.join(5)
    stall = max(gaps) * 1e3 - 2
    rate = renders["count"] / SECONDS
    print(
        f"live stream: 2 x {FS:g} S/s in periods of {N} samples ({len(plan.lines)} lines), "
        f"{SECONDS:g} s"
    )
    print("| figure | idle window (baseline) | during the live run | target |")
    print("| --- | --- | --- | --- |")
    print(f"| longest GUI-thread stall | {idle:.1f} ms | {stall:.1f} ms | < 50 ms |")
    print(f"| plot updates per second | | {rate:.1f} | >= 20 |")
    window.close()
    sys.stdout.flush()
    os._exit(0)  # skip PySide6's interpreter teardown, which can crash after the figures


if __name__ == "__main__":
    main()
