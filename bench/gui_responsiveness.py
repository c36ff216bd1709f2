"""GUI responsiveness during a live run at 2 x 51.2 kS/s (SPEC.md s.11-12, issue 6).

A feeder thread plays the worker's part: every 50 ms it emits the events of one period of a
51.2 kS/s plan with 50 ms periods (2 channels x 2560 samples, a live estimate of 34 lines), the
fastest stream the GUI can meet. Measured on the GUI thread: the longest stall (a 2 ms
heartbeat timer's largest gap beyond its interval) and the plot updates per second.
Targets: stall < 50 ms, >= 20 updates per second. The heartbeat's own gap with an idle window,
measured first in the same run, is the baseline.

Run: QT_QPA_PLATFORM=offscreen python bench/gui_responsiveness.py
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

from PySide6.QtCore import QObject, QTimer, Signal
from PySide6.QtWidgets import QApplication

from app.gui.main_window import MainWindow
from app.procedure import PeriodBlock, PeriodEstimate, State
from dsp import iso266
from dsp.calibration import ReferenceChain, compute_results
from dsp.multisine import make_plan
from dsp.spectral import SpectralAccumulator
from dsp.uncertainty import Budget

FS, N, SECONDS = 51_200.0, 2560, 6.0


class Feeder(QObject):
    event = Signal(object)


def main() -> None:
    app = QApplication(sys.argv[:1])
    window = MainWindow(out=Path("/tmp/bench-gui-runs"), paced=False)
    window.resize(1400, 900)
    window.show()
    freqs = [f for f in iso266.nominal_frequencies(20, 20_000) if round(f * N / FS) * FS / N == f]
    plan = make_plan(freqs, FS, N, 5.0, freqs[len(freqs) // 2], phases_rad=np.zeros(len(freqs)))
    window._buffer = {"plan": plan}
    feeder = Feeder()
    feeder.event.connect(window._on_event)
    renders = {"count": 0}
    original = window._render

    def counted() -> None:
        dirty = window._dirty
        original()
        renders["count"] += dirty

    window.timer.timeout.disconnect()
    window.timer.timeout.connect(counted)
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
    stop = threading.Event()

    def feed() -> None:
        rng = np.random.default_rng(0)
        i = np.arange(N)
        u0 = sum(np.sin(2 * np.pi * m * i / N + 0.3 * k) for k, m in enumerate(plan.bins)) * 0.02
        acc = SpectralAccumulator(N, plan.bins)
        chain = ReferenceChain.flat(1.0)
        k = 0
        while not stop.is_set():
            t0 = time.perf_counter()
            noise = 1e-4 * rng.standard_normal((2, N))
            block = np.vstack([u0, 0.5 * u0]) + noise
            acc.add_period(block[0], block[1])
            k += 1
            feeder.event.emit(PeriodBlock(k, State.ACQUIRING, ("reference", "dut"), block, u0))
            if k >= 2:
                estimate = acc.estimate()
                results = compute_results(estimate, plan, chain, Budget(()))
                feeder.event.emit(PeriodEstimate(k, estimate, results))
            time.sleep(max(0.0, N / FS - (time.perf_counter() - t0)))

    thread = threading.Thread(target=feed, daemon=True)
    renders["count"] = 0
    thread.start()
    phase(SECONDS)
    stop.set()
    thread.join()
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
