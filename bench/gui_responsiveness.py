"""GUI responsiveness during a live run at 2 x 51.2 kS/s (SPEC s.11-12, issues 6 and 27).

A stand-in procedure on the real run worker (`app.gui.worker.RunWorker`, a plain thread that
queues copies of events for the Run tab's FRAME_HZ timer) streams 2 x 51.2 kS/s in periods of
1280 samples (25 ms: 40 periods a second, faster than the frame timer, so every frame has a new
period to draw) with a live estimate of its lines after each period, the fastest stream the GUI
can meet. Measured on the GUI thread: the longest stall (a 2 ms heartbeat timer's largest gap
beyond its interval), the live plot updates per second (frames that drew a new period) and
the GUI thread's own CPU time per update, which the machine's load does not inflate.
Targets: stall < 50 ms, >= 30 updates per second. The heartbeat's own gap with an idle window,
measured first in the same run, is the baseline. The run then ends as an aborted run ends
(a `Finished` with its `RunRecord`) and the window closes: the script runs to its end.

Run:   QT_QPA_PLATFORM=offscreen python bench/gui_responsiveness.py [--smoke]
--smoke: 1 s of stream instead of 6 (CI: checks the script runs, not the figures).
Exit 0 when the targets are met (always in smoke mode, where the figures are too short to judge).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication

from app.gui.main_window import MainWindow
from app.io.vocabulary import RunStatus
from app.procedure import Finished, PeriodBlock, PeriodEstimate, State, StateChanged
from app.records.run_record import RunRecord
from dsp import iso266
from dsp.calibration import ReferenceChain, compute_results
from dsp.multisine import Plan, make_plan
from dsp.spectral import SpectralAccumulator
from dsp.uncertainty import Budget

FS, N = 51_200.0, 1280
TARGET_STALL_MS, TARGET_RATE = 50.0, 30.0


class FeedingProcedure:
    """Plays a procedure's part for the worker: streams period and estimate events in real
    time until aborted, then ends as an aborted run ends (its record at 0 V)."""

    def __init__(self, plan: Plan) -> None:
        self.plan = plan
        self.listener: Any = None
        self.stop = threading.Event()
        self.reason = ""

    def abort(self, reason: str = "") -> None:
        self.reason = reason or "stopped"
        self.stop.set()

    emergency_stop = abort

    def run(self) -> Finished:
        plan, emit = self.plan, self.listener
        rng = np.random.default_rng(0)
        i = np.arange(N)
        u0 = sum(np.sin(2 * np.pi * m * i / N + 0.3 * k) for k, m in enumerate(plan.bins)) * 0.02
        acc = SpectralAccumulator(N, plan.bins)
        chain = ReferenceChain.flat(1.0)
        emit(StateChanged(State.ACQUIRING, "bench stream"))
        k = 0
        started = time.perf_counter()
        while not self.stop.is_set():
            noise = 1e-4 * rng.standard_normal((2, N))
            block = np.vstack([u0, 0.5 * u0]) + noise
            acc.add_period(block[0], block[1])
            k += 1
            emit(PeriodBlock(k, State.ACQUIRING, ("reference", "dut"), block, u0))
            if k >= 2:
                estimate = acc.estimate()
                emit(
                    PeriodEstimate(k, estimate, compute_results(estimate, plan, chain, Budget(())))
                )
            # real time: period k ends at k * N / FS after the start
            time.sleep(max(0.0, started + k * N / FS - time.perf_counter()))
        record = RunRecord(
            run_id=None, status=RunStatus.ABORTED, abort_reason=self.reason, final_output_v=0.0
        )
        return Finished(RunStatus.ABORTED, self.reason, None, record)


class NoStand:
    def close(self) -> None:
        pass


def bench_plan() -> Plan:
    """ISO 266 lines of 20 Hz to 20 kHz that fall on a bin of the 1280-sample period."""
    freqs = [f for f in iso266.nominal_frequencies(20, 20_000) if round(f * N / FS) * FS / N == f]
    return make_plan(freqs, FS, N, 5.0, freqs[len(freqs) // 2], phases_rad=np.zeros(len(freqs)))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="1 s of stream (CI)")
    args = parser.parse_args(argv)
    seconds, idle_s = (1.0, 0.3) if args.smoke else (6.0, 1.0)
    app = QApplication.instance() or QApplication(sys.argv[:1])
    work = Path(tempfile.mkdtemp(prefix="bench-gui-"))
    # no records (never the user's own): the window says so and works without them
    window = MainWindow(out=work / "runs", paced=False, db=f"sqlite:///{work / 'none.sqlite'}")
    window.records.wait()
    window.resize(1366, 768)
    window.show()
    tab = window.run_tab
    window.tabs.setCurrentWidget(tab)
    plan = bench_plan()
    renders = {"count": 0}
    original = tab.live.draw_period

    def counted(*a: Any) -> None:
        original(*a)
        renders["count"] += 1

    tab.live.draw_period = counted  # type: ignore[method-assign]
    gaps: list[float] = []
    last = {"t": time.perf_counter()}

    def beat() -> None:
        now = time.perf_counter()
        gaps.append(now - last["t"])
        last["t"] = now

    heartbeat = QTimer(interval=2, timeout=beat)
    heartbeat.start()

    def spin(until: Any) -> None:
        while not until():
            app.processEvents()
            time.sleep(0.001)

    def run_for(s: float) -> None:
        end = time.perf_counter() + s
        spin(lambda: time.perf_counter() >= end)

    run_for(idle_s)
    idle = max(gaps) * 1e3 - 2
    gaps.clear()
    procedure = FeedingProcedure(plan)
    ended: list[Any] = []
    tab.ended.connect(ended.append)
    renders["count"] = 0
    cpu0 = time.thread_time()  # the GUI thread's own CPU time: the machine's load aside
    tab.attach(procedure, NoStand(), {"reference": 10.0, "dut": 10.0})  # as Start does
    run_for(seconds)
    cpu_ms = (time.thread_time() - cpu0) * 1e3
    stall = max(gaps) * 1e3 - 2
    rate = renders["count"] / seconds
    per_frame = cpu_ms / max(1, renders["count"])
    heartbeat.stop()
    tab.stop()  # as the operator: the run ends aborted, through the tab's own path
    spin(lambda: bool(ended))
    finished = ended[0]
    print(
        f"live stream: 2 x {FS:g} S/s in periods of {N} samples ({len(plan.lines)} lines), "
        f"{seconds:g} s{' (smoke)' if args.smoke else ''}"
    )
    print("| figure | idle window (baseline) | during the live run | target |")
    print("| --- | --- | --- | --- |")
    print(
        f"| longest GUI-thread stall | {idle:.1f} ms | {stall:.1f} ms | < {TARGET_STALL_MS:g} ms |"
    )
    print(f"| plot updates per second | | {rate:.1f} | >= {TARGET_RATE:g} |")
    print(
        f"| GUI-thread CPU per update (heartbeat included) | | {per_frame:.1f} ms "
        f"(room for {1e3 / per_frame:.0f} updates/s) | <= {1e3 / TARGET_RATE:.0f} ms |"
    )
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores during the run")
    print(f"run ended: {finished.status} ({finished.abort_reason}); Run tab: {tab.state.text()}")
    window.close()
    app.processEvents()
    met = stall < TARGET_STALL_MS and rate >= TARGET_RATE
    return 0 if met or args.smoke else 1


if __name__ == "__main__":
    raise SystemExit(main())
