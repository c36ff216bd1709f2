"""The run worker: a plain thread that runs one procedure and queues copies of its events.

It never touches a widget, a plot item or any Qt object: the window's timer drains the queue
on the GUI thread. The procedure writes the run's record itself (recording flushed per period,
results.json and manifest at the end), so the record does not depend on the window: if the
GUI died mid-run, the folder stays readable and is listed as "interrupted".
"""

from __future__ import annotations

import collections
import dataclasses
import logging
import threading
from typing import Any

import numpy as np

from app.io.vocabulary import RunStatus
from app.procedure import Event, Finished, PeriodBlock, Procedure
from app.records.run_record import RunRecord

log = logging.getLogger(__name__)

MAX_QUEUED = 2000  # events kept when the GUI falls behind (oldest dropped; Finished never)


def copied(event: Event) -> Event:
    """The event with its arrays copied: the procedure may reuse its buffers."""
    if isinstance(event, PeriodBlock):
        return dataclasses.replace(
            event, samples=np.array(event.samples, copy=True), drive=np.array(event.drive)
        )
    return event


class RunWorker:
    """Runs `procedure` on its own thread, then closes `stand`; events go to `drain()`."""

    def __init__(self, procedure: Procedure, stand: Any) -> None:
        self.procedure = procedure
        self.stand = stand
        self.finished: Finished | None = None
        self._events: collections.deque[Event] = collections.deque(maxlen=MAX_QUEUED)
        self._lock = threading.Lock()
        procedure.listener = self._on_event
        self.thread = threading.Thread(target=self._run, name="calibration-run", daemon=True)

    def start(self) -> None:
        self.thread.start()

    def is_alive(self) -> bool:
        return self.thread.is_alive()

    def join(self, timeout_s: float | None = None) -> bool:
        """Wait for the run to end; whether it has."""
        self.thread.join(timeout_s)
        return not self.thread.is_alive()

    def drain(self) -> list[Event]:
        """The events queued since the last call (GUI thread)."""
        with self._lock:
            events = list(self._events)
            self._events.clear()
        return events

    @property
    def done(self) -> bool:
        """The run has ended and its last event has been queued."""
        return self.finished is not None and not self.thread.is_alive()

    def _on_event(self, event: Event) -> None:
        if isinstance(event, Finished):
            return  # kept apart in `finished`, never dropped from a full queue
        with self._lock:
            self._events.append(copied(event))

    def _run(self) -> None:
        try:
            finished = self.procedure.run()
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
        self.finished = finished
