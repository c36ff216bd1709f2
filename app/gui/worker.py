"""The run worker: a plain thread that runs one procedure and queues copies of its events.

It never touches a widget, a plot item or any Qt object: the window's timer drains the queue
on the GUI thread. What the live plots show of a period or an estimate is computed here, on the
worker's thread, as the event arrives (`app.gui.live_view`): the GUI thread only sets points.
The procedure writes the run's record itself (recording flushed per period, results.json and
manifest at the end), so the record does not depend on the window: if the GUI died mid-run,
the folder stays readable and is listed as "interrupted".
"""

from __future__ import annotations

import collections
import dataclasses
import importlib
import logging
import sys
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from app.gui.live_view import MIN_COLUMNS, EstimateView, PeriodView, block_view, estimate_view
from app.io.vocabulary import RunStatus
from app.procedure import (
    Event,
    Finished,
    PeriodBlock,
    PeriodEstimate,
    Procedure,
    State,
    StateChanged,
)
from app.records.run_record import RunRecord
from hardware.errors import HardwareError

log = logging.getLogger(__name__)

# modules a run imports on its first use (the simulated stand's models: sim.lti, sim.models);
# an import holds the GIL for its length (about 1 s of scipy at load), so imported on the run
# worker's thread they stalled the window's thread that long just after Start
RUN_IMPORTS = ("scipy.signal", "scipy.linalg")
MAX_QUEUED = 2000  # events kept when the GUI falls behind (oldest dropped; Finished never)
VIEW_WAIT_S = 0.5  # s, the longest a run waits for the tab to paint its opened plots
# the GIL's switch interval (s) from the first run worker's start on (the process's setting, it
# stays): a thread that waits for the GIL asks the holder for it after this long (CPython's
# default is 5 ms). The window's thread takes the GIL back at every Python callback Qt makes
# (each pyqtgraph item's paint, each timer slot), so with a run worker computing (estimation,
# the preflight's synthesis) a frame of N callbacks waited up to N x 5 ms: the 50-56 ms stalls
# of issue 34 point 6 with 7 ms of the window's own work (bench/gil_holds.py). A shorter
# interval costs the worker only a switch per interval while the window waits.
GIL_SWITCH_S = 0.0005


def hand_gil_over_sooner(interval_s: float | None = None) -> float:
    """Shorten the interpreter's GIL switch interval to `interval_s` (None: GIL_SWITCH_S as the
    module holds it when called; never lengthened: a shorter one set by the caller stays);
    the interval now in force (s)."""
    interval_s = GIL_SWITCH_S if interval_s is None else interval_s
    if sys.getswitchinterval() > interval_s:
        sys.setswitchinterval(interval_s)
    return sys.getswitchinterval()


def copied(event: Event) -> Event:
    """The event with its arrays copied: the procedure may reuse its buffers."""
    if isinstance(event, PeriodBlock):
        return dataclasses.replace(
            event, samples=np.array(event.samples, copy=True), drive=np.array(event.drive)
        )
    return event


@dataclass(frozen=True)
class ShownPeriod:
    """A period as queued for the GUI: the block (copied) and its view (None: it could not
    be made; the tab then draws the block as it is)."""

    block: PeriodBlock
    view: PeriodView | None


@dataclass(frozen=True)
class ShownEstimate:
    """A live estimate as queued for the GUI: the event and its view (None: see ShownPeriod),
    and in a run of several DUTs the view of each other DUT's estimate the event carries, by
    position (`PeriodEstimate.members`; empty: not made, the tab makes them)."""

    estimate: PeriodEstimate
    view: EstimateView | None
    members: Mapping[str, EstimateView] = dataclasses.field(default_factory=dict)


def warm_imports() -> threading.Thread:
    """Import RUN_IMPORTS on a thread of their own as the window opens, before any Start;
    the thread (to join when the figures must not include it: bench, tests)."""

    def load() -> None:
        for name in RUN_IMPORTS:
            try:
                importlib.import_module(name)
            except ImportError:  # the run says so itself if it needs the module
                log.warning("could not import %s ahead of a run", name)

    thread = threading.Thread(target=load, name="warm-imports", daemon=True)
    thread.start()
    return thread


@dataclass(frozen=True)
class Opened:
    """The stand is open and the run has its procedure (queued first, on the worker's thread):
    the tab lays its plots out for the procedure's plan."""

    procedure: Any


class RunWorker:
    """Runs `procedure` on its own thread, then closes `stand`; events go to `drain()`.

    `RunWorker.opening(opener)` opens the run on the worker's thread too: `opener()` returns
    (procedure, stand) and may take a second (the plan, the input ranges, the stand's drivers),
    which the window's thread must not wait for. An `Opened` event is queued once it has; a
    refusal (ValueError, HardwareError) is kept in `refusal` and the worker ends without a run.
    `ending(finished, listener)`, when given, is called on the worker's thread after the stand
    is closed (a batch's other DUTs estimated and sealed: `OpenedBatch.end`); what it returns
    is kept in `ended` before `finished` is set.
    """

    def __init__(self, procedure: Procedure | None, stand: Any) -> None:
        self.procedure = procedure
        self.stand = stand
        self.finished: Finished | None = None
        self.refusal: Exception | None = None  # why the run could not be opened
        self.state: State | None = None  # the run's phase as its last StateChanged said
        self._opener: Callable[[], tuple[Procedure, Any]] | None = None
        self._ending: Callable[[Finished, Callable[[Event], None]], Any] | None = None
        self.ended: Any = None  # what `ending` returned (a batch's BatchFinished)
        self._stop: tuple[str, bool] | None = None  # (reason, emergency) asked before opening
        self._events: collections.deque[Any] = collections.deque(maxlen=MAX_QUEUED)
        self._lock = threading.Lock()
        # pixel columns of the live plots (the GUI thread sets it as the window resizes)
        self.columns = MIN_COLUMNS
        self._view_failed = False
        # set by the tab once it has painted the opened run's plots (`opened`): the run waits
        # for it (at most VIEW_WAIT_S) so the first paint does not compete with the run's
        # start for the interpreter (the GUI's longest stall, issue 34.6); set from the start
        # for a worker nobody shows
        self.view_ready = threading.Event()
        self.view_ready.set()
        if procedure is not None:
            procedure.listener = self._on_event
        self.thread = threading.Thread(target=self._run, name="calibration-run", daemon=True)

    @classmethod
    def opening(
        cls,
        opener: Callable[[], tuple[Procedure, Any]],
        ending: Callable[[Finished, Callable[[Event], None]], Any] | None = None,
    ) -> RunWorker:
        """A worker that opens its run itself, and ends it with `ending` (see the class)."""
        worker = cls(None, None)
        worker._opener = opener
        worker._ending = ending
        return worker

    def start(self) -> None:
        hand_gil_over_sooner()
        self.thread.start()

    def is_alive(self) -> bool:
        return self.thread.is_alive()

    def join(self, timeout_s: float | None = None) -> bool:
        """Wait for the run to end; whether it has."""
        self.thread.join(timeout_s)
        return not self.thread.is_alive()

    def abort(self, reason: str) -> None:
        """Fade the drive out and end the run (before it is open: it ends as soon as it is)."""
        self._ask_stop(reason, emergency=False)

    def emergency_stop(self) -> None:
        """The drive to 0 V at once (before the run is open: as `abort`, nothing plays yet)."""
        self._ask_stop("emergency stop", emergency=True)

    def _ask_stop(self, reason: str, *, emergency: bool) -> None:
        with self._lock:
            procedure = self.procedure
            if procedure is None:
                self._stop = (reason, emergency)
                return
        if emergency:
            procedure.emergency_stop()
        else:
            procedure.abort(reason)

    def drain(self) -> list[Any]:
        """The events queued since the last call (GUI thread): periods and estimates as
        `ShownPeriod` and `ShownEstimate`, the others as the procedure sent them."""
        with self._lock:
            events = list(self._events)
            self._events.clear()
        return events

    @property
    def done(self) -> bool:
        """The run has ended (or could not be opened) and its last event has been queued."""
        ended = self.finished is not None or self.refusal is not None
        return ended and not self.thread.is_alive()

    def _on_event(self, event: Event) -> None:
        if isinstance(event, Finished):
            return  # kept apart in `finished`, never dropped from a full queue
        if isinstance(event, StateChanged):
            self.state = event.state
        shown = self._shown(copied(event))
        with self._lock:
            self._events.append(shown)

    def _shown(self, event: Event) -> Any:
        """`event` with what the live plots show of it (a period or an estimate), made on this
        thread. A view that cannot be made never ends the run: it is logged once and the
        event queued without it."""
        try:
            procedure = self.procedure  # set before the listener is
            if isinstance(event, PeriodBlock) and procedure is not None:
                view = block_view(event.samples, event.channels, procedure.plan, self.columns)
                return ShownPeriod(event, view)
            if isinstance(event, PeriodEstimate):
                members = {m.position: estimate_view(m.results) for m in event.members}
                return ShownEstimate(event, estimate_view(event.results), members)
        except Exception:
            if not self._view_failed:
                log.exception("the live view of a %s could not be made", type(event).__name__)
                self._view_failed = True
            if isinstance(event, PeriodBlock):
                return ShownPeriod(event, None)
            if isinstance(event, PeriodEstimate):
                return ShownEstimate(event, None)
        return event

    def _open(self) -> bool:
        """Open the run (`opening`) on this thread; whether there is a run to play."""
        if self._opener is None:
            return True
        try:
            procedure, stand = self._opener()
        except (ValueError, HardwareError) as exc:  # config, plan, missing driver or device
            self.refusal = exc
            return False
        except BaseException as exc:  # a last resort, as in `_run`
            log.exception("the run could not be opened")
            self.refusal = exc if isinstance(exc, Exception) else RuntimeError(str(exc))
            return False
        procedure.listener = self._on_event
        with self._lock:
            self.procedure, self.stand = procedure, stand
            self._events.appendleft(Opened(procedure))
            stop = self._stop
        if stop is not None:  # stopped while opening: the run ends at once, with its record
            reason, emergency = stop
            procedure.emergency_stop() if emergency else procedure.abort(reason)
        return True

    def _run(self) -> None:
        if not self._open():
            return
        procedure = self.procedure
        assert procedure is not None
        self.view_ready.wait(VIEW_WAIT_S)
        try:
            finished = procedure.run()
        except BaseException as exc:  # the procedure catches its own; this is a last resort
            log.exception("the run ended with an unexpected error")
            reason = f"internal error: {type(exc).__name__}: {exc}"
            record = RunRecord(run_id=None, status=RunStatus.ABORTED, abort_reason=reason)
            finished = Finished(RunStatus.ABORTED, reason, None, record)
        finally:
            try:
                self.stand.close()
            except Exception:
                log.exception("closing the stand failed")
        if self._ending is not None:
            try:
                self.ended = self._ending(finished, self._on_event)
            except Exception:  # the run's own record stands; the others' end is logged
                log.exception("the run's end (the other DUTs of the batch) failed")
        self.finished = finished
