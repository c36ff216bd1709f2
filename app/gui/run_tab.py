"""The Run tab: one run live (state, equalisation, coherence, progress, input meters in % of
range, the last period and the characteristic so far) and its Stop button.

The procedure runs on a plain worker thread (`app.gui.worker.RunWorker`) that only queues copies
of its events; a FRAME_HZ timer on the GUI thread drains the queue into a `LiveFrame` (the latest
of each kind) and draws it, so no widget or plot item is touched from another thread. When the
worker is done the tab says how the run ended and emits `ended` with the `Finished` (or None).
"""

from __future__ import annotations

import gc
import html
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtGui import QFontMetrics
from PySide6.QtWidgets import (
    QHBoxLayout,
    QLabel,
    QMessageBox,
    QProgressBar,
    QPushButton,
    QSizePolicy,
    QVBoxLayout,
    QWidget,
)

from app.gui.live_view import EstimateView, PeriodView, block_view, estimate_view, own_dut
from app.gui.plots import FRAME_HZ, LivePlots
from app.gui.results_tab import wrapping_label
from app.gui.table_items import shown_unit
from app.gui.worker import Opened, RunWorker, ShownEstimate, ShownPeriod
from app.io.vocabulary import RunStatus
from app.procedure import (
    EqualisationStep,
    Finished,
    InputRanges,
    PeriodBlock,
    PeriodEstimate,
    Progress,
    State,
    StateChanged,
    WarningRaised,
)
from app.procedure.service import PreparedRun, RunService
from dsp.calibration import Results
from dsp.multisine import Plan

if TYPE_CHECKING:
    from app.procedure.batch import MemberChoice

log = logging.getLogger(__name__)

STOP_STYLE = (  # flat colours (a border makes Qt draw the background as given)
    "QPushButton { background: #c0392b; color: white; font-weight: bold; padding: 8px;"
    " border: 1px solid #922b21; border-radius: 4px; }"
    "QPushButton:disabled { background: #e5e7e9; color: #a6acaf; font-weight: normal;"
    " border: 1px solid #ccd1d1; }"
)
METERED = ("reference", "dut")  # the input channels with a level meter (one DUT)
METERED_NAMES = {name: name for name in METERED}
OPENING_S = 5.0  # s a run still opening is given to open before it is stopped (closing)
METER_STYLE = "QProgressBar::chunk {background: %s}"  # the meter's colour: red near full


@dataclass(frozen=True)
class PhaseSteps:
    """How many steps the phases before acquisition take (the run's settings): background
    periods and at most so many equalisation iterations."""

    background_periods: int = 2
    equalisation_iterations: int = 8

    @classmethod
    def of(cls, procedure: Any) -> PhaseSteps:
        """The steps of `procedure`'s settings (the defaults when it has none)."""
        settings = getattr(procedure, "settings", None)
        if settings is None:
            return cls()
        return cls(
            max(1, int(settings.background_periods)),
            max(1, int(settings.max_equalisation_iterations)),
        )


@dataclass
class LiveFrame:
    """What the next frame draws: the latest event of each kind since the last frame (None:
    nothing new), the run's plan, and the warnings so far. The progress bar shows the phase
    the run is in and how far it is through it: background periods read of those planned,
    equalisation iterations of at most so many, acquisition's own fraction and time left."""

    plan: Plan | None = None
    steps: PhaseSteps = field(default_factory=PhaseSteps)
    block: PeriodBlock | None = None
    view: PeriodView | None = None  # the block's, made by the worker (None: made at drawing)
    estimate: PeriodEstimate | None = None
    estimate_view: EstimateView | None = None  # the estimate's, as `view`
    # a run of several DUTs: the first member's position (its estimates come with it, or
    # with no member) and the latest results of each member not drawn yet, by position (the
    # others' come in the first member's estimate, and each one's stored results at the end)
    lead: str = ""
    members: dict[str, tuple[Results, EstimateView | None]] = field(default_factory=dict)
    state: str | None = None
    equalisation: str | None = None
    progress: tuple[float, str] | None = None  # (fraction of the phase done, what it says)
    warnings: list[str] = field(default_factory=list)
    ranges: str | None = None  # the input ranges the run picked, or a line re-ranged
    phase: State | None = None
    phase_blocks: int = 0  # periods read in this phase

    def take(self, events: list[Any]) -> None:
        """Keep only what the next frame draws."""
        for item in events:
            event: Any = item
            view: Any = None  # the worker's view of a period or an estimate
            member_views: Mapping[str, EstimateView] = {}  # the other DUTs' (worker's)
            if isinstance(item, ShownPeriod):
                event, view = item.block, item.view
            elif isinstance(item, ShownEstimate):
                event, view, member_views = item.estimate, item.view, item.members
            if isinstance(event, PeriodBlock):
                if event.state != State.FADING_OUT:  # keep showing the last steady period
                    self.block, self.view = event, view
                if event.state == State.BACKGROUND and self.phase == State.BACKGROUND:
                    self.phase_blocks += 1
                    n = self.steps.background_periods
                    done = min(self.phase_blocks, n)
                    self.progress = (done / n, f"background: period {done} of {n}")
            elif isinstance(event, PeriodEstimate):
                member = event.member or self.lead
                if member:
                    self.members[member] = (event.results, view)
                if member == self.lead:  # the run's own DUT: coherence, U and phase
                    self.estimate, self.estimate_view = event, view
                for other in event.members:  # the other DUTs after the same period
                    self.members[other.position] = (other.results, member_views.get(other.position))
            elif isinstance(event, StateChanged):
                self.state = f"{event.state}: {event.message}" if event.message else event.state
                self.phase, self.phase_blocks = event.state, 0
                self.progress = self.phase_start(event.state)
            elif isinstance(event, EqualisationStep):
                self.equalisation = (
                    f"equalisation {event.iteration}: worst line {100 * event.worst:.2f} %"
                )
                n = self.steps.equalisation_iterations
                self.progress = (
                    min(event.iteration / n, 1.0),
                    f"equalisation {event.iteration} of at most {n}",
                )
            elif isinstance(event, Progress):
                left = (
                    "" if event.remaining_s is None else f", about {event.remaining_s:.0f} s left"
                )
                self.progress = (event.fraction, f"acquiring {100 * event.fraction:.0f} %{left}")
            elif isinstance(event, WarningRaised):
                self.warnings.append(event.text)
            elif isinstance(event, InputRanges):
                self.ranges = event.text

    def phase_start(self, state: State) -> tuple[float, str]:
        """The bar as a phase begins."""
        if state == State.BACKGROUND:
            return 0.0, f"background: period 0 of {self.steps.background_periods}"
        if state == State.EQUALISING:
            return 0.0, f"equalisation 0 of at most {self.steps.equalisation_iterations}"
        if state == State.ACQUIRING:
            return 0.0, "acquiring"
        return (1.0 if state == State.FINISHED else 0.0), str(state)


class ElidedLabel(QLabel):
    """One line of text, elided to the width it is given (the whole text in the tooltip);
    it never widens its window."""

    def __init__(self, text: str = "") -> None:
        super().__init__()
        self._full = ""
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.setMinimumWidth(1)
        self.setText(text)

    def setText(self, text: str) -> None:
        self._full = text
        self._elide()

    def text(self) -> str:
        return self._full

    def resizeEvent(self, event: Any) -> None:
        super().resizeEvent(event)
        self._elide()

    def _elide(self) -> None:
        width = max(self.width(), 40)
        shown = QFontMetrics(self.font()).elidedText(self._full, Qt.TextElideMode.ElideRight, width)
        super().setText(shown)
        # the whole text in the tooltip whenever any of it is cut (or it is long)
        self.setToolTip(self._full if shown != self._full or len(self._full) > 60 else "")

    def sizeHint(self) -> Any:
        """As wide as the whole text (the layout gives it that when it can)."""
        hint = super().sizeHint()
        hint.setWidth(QFontMetrics(self.font()).horizontalAdvance(self._full) + 8)
        return hint


class RunTab(QWidget):
    """The live view of one run and the worker that runs it."""

    ended = Signal(object)  # Finished | None, on the GUI thread, once per run

    def __init__(self) -> None:
        super().__init__()
        self.worker: RunWorker | None = None
        self.out: Path | None = None  # the runs root of the run going or last run
        self.frame = LiveFrame()
        self.ranges_v: dict[str, float] = {}  # input range (V) of each metered channel
        # a run of several DUTs: the legend of each member's curve by position, in the
        # fixture's order ({}: one DUT), and how the batch ended (BatchFinished, None)
        self.labels: dict[str, str] = {}
        self.batch: Any = None
        layout = QVBoxLayout(self)
        top = QHBoxLayout()
        self.state = ElidedLabel("idle")
        self.state.setStyleSheet("font-size: 15px; font-weight: bold")
        self.equalisation = ElidedLabel("")
        self.coherence = ElidedLabel("")
        self.progress = QProgressBar()
        self.stop_button = QPushButton("Stop (fade out)  Ctrl+.")
        self.stop_button.setStyleSheet(STOP_STYLE)  # disabled: grey, visibly not active
        self.stop_button.clicked.connect(self.stop)
        self.stop_button.setEnabled(False)
        # the state on a row of its own, as wide as the window: never cut at 1366 px
        top.addWidget(self.state, 1)
        top.addWidget(self.stop_button)
        layout.addLayout(top)
        details = QHBoxLayout()
        details.addWidget(self.equalisation, 2)
        details.addWidget(self.coherence, 3)
        details.addWidget(self.progress, 3)
        layout.addLayout(details)
        self.ranges_label = ElidedLabel("")  # the input ranges the run uses (issue 32)
        layout.addWidget(self.ranges_label)
        self.meter_row = QHBoxLayout()
        self.meters: dict[str, QProgressBar] = {}  # a level meter per metered input channel
        self.meter_names: dict[str, str] = {}  # what each meter calls its channel
        self.set_meters(METERED_NAMES)
        layout.addLayout(self.meter_row)
        self.live = LivePlots()
        layout.addWidget(self.live.widget, 1)
        self.messages = wrapping_label("")
        self.messages.setTextFormat(Qt.TextFormat.RichText)
        layout.addWidget(self.messages)
        self.timer = QTimer(self, interval=int(1000 / FRAME_HZ))
        self.timer.timeout.connect(self.tick)
        self.timer.start()

    @property
    def procedure(self) -> Any:
        """The running procedure (None when idle)."""
        return self.worker.procedure if self.worker is not None else None

    def begin(
        self,
        service: RunService,
        prepared: PreparedRun,
        ranges_v: Mapping[str, float],
        note: str | None,
        members: Sequence[MemberChoice] = (),
    ) -> bool:
        """Open the stand and start the `prepared` run (the run service's) on a worker, both
        off this thread; `ranges_v` the input range (V) of each metered channel, `note` a word
        to show; `members` the DUTs of a run of several on the stand's fixture (the service's
        `start_batch`; each one's deviation drawn, `batch` set when it ends). False when a run
        is going already; a run that cannot be opened ends as Start's refusal did (`end`: a
        message box, the reason shown, `ended` with None)."""
        if self.worker is not None:
            return False
        self.out = prepared.request.out
        # the stand opened and the plan made on the worker's thread: a second at 51.2 kS/s
        # that the window's thread does not wait for (`RunWorker.opening`)
        if members:
            opening = BatchOpening(service, prepared, tuple(members))
            worker = RunWorker.opening(opening.open, opening.end)
            labels = {m.position: f"{m.position} · {m.serial}" for m in opening.ordered()}
        else:
            worker, labels = RunWorker.opening(lambda: service.start(prepared)), {}
        self._start(worker, ranges_v, None, labels)
        self.state.setText("opening the stand ...")
        if note:
            self.messages.setText(html.escape(note))
        return True

    def attach(self, procedure: Any, stand: Any, ranges_v: Mapping[str, float]) -> None:
        """Show the live run of `procedure` on the opened `stand` from a worker thread, from an
        empty tab."""
        self._start(RunWorker(procedure, stand), ranges_v, procedure)

    def _start(
        self,
        worker: RunWorker,
        ranges_v: Mapping[str, float],
        procedure: Any | None,
        labels: Mapping[str, str] | None = None,
    ) -> None:
        """Start `worker` from an empty tab (`procedure`: the run's, when it is open already).
        While it runs, the objects older than the run are frozen out of Python's garbage
        collector (`gc.freeze`): a full collection then scans only what the run made, so it
        cannot stall the window for tens of ms (measured: 50-90 ms unfrozen)."""
        self.clear()
        self.state.setText("starting ...")
        self.ranges_v = dict(ranges_v)
        self.labels, self.batch = dict(labels or {}), None
        self.frame = LiveFrame(lead=next(iter(self.labels), ""))
        # a run of several DUTs: the reference's meter and each DUT's channel's, named as
        # its curve is; one DUT: the reference's and the DUT's
        members = {f"dut.{position}": label for position, label in self.labels.items()}
        self.set_meters({"reference": "reference", **members} if members else dict(METERED_NAMES))
        # each DUT's curve and legend made here, before the worker starts to compete for the
        # interpreter (in `opened` they stalled the window's thread tens of ms)
        self.live.members(self.labels)
        if procedure is not None:
            self.opened(procedure)
        else:  # the run waits for its plots to be painted once it has opened (`opened`)
            worker.view_ready.clear()
        self.worker = worker
        self.stop_button.setEnabled(True)
        gc.freeze()
        worker.start()

    def opened(self, procedure: Any) -> None:
        """The run is open: the plots laid out with its plan's x ranges before its first
        period, the progress with its phases' steps."""
        self.frame.plan, self.frame.steps = procedure.plan, PhaseSteps.of(procedure)
        self.live.prepare(procedure.plan)
        if self.worker is not None:  # painted now, while the run waits for it (RunWorker)
            self.live.graphics.viewport().repaint()
            self.worker.view_ready.set()

    def stop(self) -> None:
        """Fade the drive out and end the run (kept as aborted)."""
        if self.worker is not None:
            self.worker.abort("stopped by the operator")
            self.state.setText("stopping: fading out ...")
            self.progress.setFormat("stopping: fading out")

    def emergency_stop(self) -> None:
        """The drive to 0 V at once."""
        if self.worker is not None:
            self.worker.emergency_stop()
            self.state.setText("EMERGENCY STOP: drive at 0 V")

    def shut_down(self, reason: str) -> None:
        """Abort a running calibration with `reason` and wait for it, bounded: a fade-out, then
        an emergency stop if the fade-out does not end (closing the window)."""
        worker = self.worker
        if worker is not None:
            procedure = worker.procedure  # None: still opening (then it ends once open)
            period = procedure.plan.period_s if procedure is not None else OPENING_S
            worker.abort(reason)
            if not worker.join(3 * period + 5):
                worker.emergency_stop()
                worker.join(period + 5)
            if worker.done:
                self.end(worker)
        self.timer.stop()

    def tick(self) -> None:
        """At most FRAME_HZ times a second, on the GUI thread: take the worker's events,
        draw the latest of each kind, and end the run in the tab once the worker has."""
        worker = self.worker
        if worker is None:
            return
        worker.columns = self.live.columns()  # the worker decimates to the plots' width
        events = worker.drain()
        if events:
            self.take(events)
            self.draw()
        if worker.done:
            self.take(worker.drain())
            self.draw()
            self.end(worker)

    def take(self, events: list[Any]) -> None:
        """Keep what the next frame draws; lay the plots out when the run has opened."""
        for event in events:
            if isinstance(event, Opened):
                self.opened(event.procedure)
        self.frame.take(events)

    def end(self, worker: RunWorker) -> None:
        """The worker is done: the run ended, or it could not be opened (said as Start said
        it: a message box and the reason under the plots)."""
        refusal = worker.refusal
        self.batch = worker.ended
        self.finish(worker.finished)
        if refusal is not None:
            text = f"{type(refusal).__name__}: {refusal}"
            self.state.setText("cannot start")
            self.messages.setText(html.escape(f"Cannot start: {refusal}"))
            QMessageBox.warning(self, "Cannot start", text)

    def draw(self) -> None:
        """Draw what the frame holds new (each piece once)."""
        frame = self.frame
        if frame.state is not None:
            self.state.setText(frame.state)
            frame.state = None
        if frame.equalisation is not None:
            self.equalisation.setText(frame.equalisation)
            frame.equalisation = None
        if frame.progress is not None:
            fraction, text = frame.progress
            frame.progress = None
            self.progress.setValue(round(100 * fraction))
            self.progress.setFormat(text)
            self.progress.setToolTip(text)
        if frame.ranges is not None:
            self.ranges_label.setText(frame.ranges)
            frame.ranges = None
        if frame.warnings:
            self.messages.setText(
                "<br/>".join(f"⚠ {html.escape(shown_unit(w))}" for w in frame.warnings[-4:])
            )
        block, frame.block = frame.block, None
        view, frame.view = frame.view, None
        if block is not None:
            if view is None and frame.plan is not None:  # queued without its view
                view = block_view(block.samples, block.channels, frame.plan, self.live.columns())
            if view is not None:
                self.live.show_period(view)
            # the range the block was read on (the run picks it), else the one it started on
            self.ranges_v.update(block.ranges_v)
            names = list(block.channels)
            for name in self.meters:
                peak = view.peaks_v.get(name) if view is not None else None
                if peak is None and shown_dut(name, names) in names:
                    row = block.samples[names.index(shown_dut(name, names))]
                    peak = float(np.max(np.abs(row))) if row.size else 0.0
                if peak is not None:
                    self.show_meter(name, int(100 * peak / self.range_v(name)))
        estimate, frame.estimate = frame.estimate, None
        shown, frame.estimate_view = frame.estimate_view, None
        if estimate is not None:
            self.show_characteristic(shown or estimate_view(estimate.results))
        members, frame.members = frame.members, {}
        for position, (member_results, member_view) in members.items():
            self.live.show_member(position, member_view or estimate_view(member_results))

    def set_meters(self, shown: Mapping[str, str]) -> None:
        """A level meter per input channel, `shown` {channel: what its meter calls it}, in
        that order (the row made anew only when they change)."""
        if list(shown.items()) == list(self.meter_names.items()):
            return
        for bar in self.meters.values():
            self.meter_row.removeWidget(bar)
            bar.deleteLater()
        self.meters, self.meter_names = {}, dict(shown)
        for name, text in shown.items():
            bar = QProgressBar(maximum=100, format=f"{text} %p % of range")
            bar.setToolTip(f"{text}: the input channel {name}'s peak in % of its range")
            self.meter_row.addWidget(bar)
            self.meters[name] = bar

    def range_v(self, name: str) -> float:
        """The +-range (V) channel `name` is read on (a DUT channel the run has not said yet:
        the DUT range it started on)."""
        return self.ranges_v.get(name) or self.ranges_v.get("dut") or 1.0

    def show_meter(self, name: str, fill: int) -> None:
        """The meter of channel `name` at `fill` % of its range (red from 95 %)."""
        bar = self.meters[name]
        shown = f"{self.meter_names.get(name, name)} %p % of ±{self.range_v(name):g} V"
        if bar.format() != shown:
            bar.setFormat(shown)
        bar.setValue(min(fill, 100))
        style = METER_STYLE % ("#c0392b" if fill >= 95 else "#27ae60")
        if bar.styleSheet() != style:  # a new style sheet re-polishes: only on change
            bar.setStyleSheet(style)

    def draw_characteristic(self, results: Results) -> None:
        """The characteristic so far and its lowest coherence (the view made here)."""
        self.show_characteristic(estimate_view(results))

    def show_characteristic(self, view: EstimateView) -> None:
        """The characteristic so far and its lowest coherence, from a view made off this
        thread (several DUTs: the first one's, named)."""
        lead = next(iter(self.labels.values()), "")
        self.coherence.setText(f"{lead}: {view.coherence}" if lead else view.coherence)
        self.live.show_characteristic(view)

    def finish(self, finished: Finished | None) -> None:
        """The run has ended (GUI thread): say how, then emit `ended`."""
        self.worker = None
        self.frame = LiveFrame()
        self.stop_button.setEnabled(False)
        gc.unfreeze()  # the run's and the older objects collectable again (`attach`)
        if finished is not None and finished.status == RunStatus.COMPLETE:
            self.state.setText("finished: results on tab 3")
            self.progress.setValue(100)
            self.progress.setFormat("complete")
        elif finished is None:
            self.progress.setFormat("ended without a result")
        else:
            self.progress.setFormat("aborted")  # never a stale "37 %, about 10 s left"
            self.progress.setToolTip(f"aborted: {finished.abort_reason}")
            run_id = finished.record.run_id
            folder = self.out / str(run_id) if run_id and self.out is not None else None
            self.state.setText(f"ABORTED: {finished.abort_reason}")
            self.messages.setText(
                f"<b>The run was aborted:</b> {html.escape(str(finished.abort_reason))}<br/>"
                f"The drive is at {finished.record.final_output_v} V. The data so far is "
                f"kept in {html.escape(str(folder))}."
            )
        self.ended.emit(finished)

    def clear(self) -> None:
        """A new run starts from an empty Run tab: no curve, meter or word of the last run."""
        self.live.clear()
        for label in (self.equalisation, self.coherence, self.ranges_label):
            label.setText("")
        self.messages.setText("")
        self.progress.setValue(0)
        self.progress.resetFormat()
        for bar in self.meters.values():
            bar.setValue(0)
            bar.setStyleSheet("")


def shown_dut(name: str, channels: Sequence[str]) -> str:
    """The channel a meter named `name` shows: the run's own DUT for "dut" (`own_dut`)."""
    return own_dut(channels) if name == "dut" else name


class BatchOpening:
    """A run of several DUTs as a RunWorker opens and ends it, on its thread: the run
    service's `start_batch`, then the batch's `end` once the stand is closed."""

    def __init__(
        self, service: RunService, prepared: PreparedRun, members: tuple[MemberChoice, ...]
    ) -> None:
        self.service, self.prepared, self.members = service, prepared, members
        self.opened: Any = None  # app.procedure.batch.OpenedBatch

    def ordered(self) -> list[MemberChoice]:
        """The members in the fixture's order (the first is the run's own DUT)."""
        from app.procedure.batch import ordered

        fixture = self.prepared.config.fixture
        return list(self.members) if fixture is None else ordered(fixture, self.members)

    def open(self) -> tuple[Any, Any]:
        """The batch opened; its other DUTs estimated live too (the tab draws each one)."""
        self.opened = self.service.start_batch(self.prepared, self.members)
        self.opened.procedure.batch_live = True
        return self.opened.procedure, self.opened.stand

    def end(self, finished: Finished, listener: Any) -> Any:
        """The other members estimated and sealed, the batch folder (BatchFinished)."""
        return self.opened.end(finished, listener)
