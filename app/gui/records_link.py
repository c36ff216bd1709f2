"""The window's link to the lab's records (`app.records.db.lab.Lab`): opened once, off the GUI
thread.

The URL is `--db URL`, else $ACCELCAL_DB, else the default SQLite file
(`app.records.db.engine`), which the window never creates: until `accelcal db upgrade` has made
it, `error` says so and how (shown in the Sensors and Register tabs). Opening may take a while
(a PostgreSQL server that does not answer); it runs on its own thread and the window polls it.
When the records cannot be opened, `error` says why and everything else in the window works
without them. Queries afterwards take milliseconds and run on the GUI thread; finishing a run
(the run service indexes it, verifying every file of its folder by SHA-256) runs on the
records' own thread, and its report comes back to the GUI thread.
Nothing here computes: it reads and writes through `Lab` and the run service only.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import TYPE_CHECKING, Any

from PySide6.QtCore import QObject, QTimer, Signal

from app.records.db.errors import RecordsInputError
from app.records.run_record import RunRecord

if TYPE_CHECKING:
    from app.procedure import Finished
    from app.procedure.service import PreparedRun, RunService

log = logging.getLogger(__name__)


def _open(url: str | None) -> Any:
    from app.records.db.engine import open_engine
    from app.records.db.lab import Lab

    return Lab(open_engine(url))


class RecordsLink(QObject):
    """`lab` once the records are open (None before, or when they cannot be: `error` says why).
    `changed` is emitted on the GUI thread when the link opens or fails."""

    changed = Signal()

    def __init__(self, url: str | None, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.url = url
        self.lab: Any = None
        self.error: str | None = None
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="records")
        self._future: Future | None = self._pool.submit(_open, url)
        self._jobs: list[tuple[Future, Callable[[str], None]]] = []
        self._timer = QTimer(self, interval=50)
        self._timer.timeout.connect(self._poll)
        self._timer.start()

    @property
    def opening(self) -> bool:
        return self._future is not None

    def wait(self, timeout_s: float = 30.0) -> None:
        """Block until opened or failed (tests, screenshots)."""
        if self._future is not None:
            try:
                self._future.result(timeout=timeout_s)
            except Exception:  # reported by _poll
                pass
            self._poll()

    def _poll(self) -> None:
        for job in [j for j in self._jobs if j[0].done()]:
            self._jobs.remove(job)
            job[1](job[0].result())  # the indexing's own report: it raises nothing
        future = self._future
        if future is None or not future.done():
            if future is None and not self._jobs:
                self._timer.stop()
            return
        self._future = None
        if not self._jobs:
            self._timer.stop()
        from app.records.db.engine import RecordsMissing

        missing = False  # none created yet (the normal first state): said, not warned
        try:
            self.lab = future.result()
        except RecordsMissing as exc:
            self.error, missing = str(exc), True
        except RecordsInputError as exc:
            self.error = str(exc)
        except Exception as exc:  # any failure of the database: the window works without it
            self.error = f"{type(exc).__name__}: {exc}"
        if self.error:
            log.log(
                logging.INFO if missing else logging.WARNING,
                "records not available: %s",
                self.error,
            )
        self.changed.emit()

    def describe(self) -> str:
        """One line: where the records are, or why they are not available."""
        if self.opening:
            return "opening the records ..."
        if self.lab is None:
            return f"records not available: {self.error}"
        return f"records: {self.lab.engine.url.render_as_string(hide_password=True)}"

    # --- reads the window needs (None / {} when the records are not available) -------------

    def sensor(self, serial: str) -> Any:
        """The sensor with exactly `serial` (never a near match), or None when unknown.
        RecordsInputError only when the records fail."""
        if self.lab is None or not serial.strip():
            return None
        from app.records.db.store import RecordsError

        try:
            return self.lab.sensor(serial)
        except RecordsError as exc:
            if "no sensor" in str(exc):
                return None
            raise

    def certificate_defaults(self, record: RunRecord) -> dict[str, str]:
        """Customer, address, model and serial of the run's sensor from the records ({} when
        the run names no sensor on record or the records are not available)."""
        serial = str((record.dut.id if record.dut else None) or "")
        try:
            sensor = self.sensor(serial)
        except RecordsInputError as exc:
            log.warning("certificate defaults not read: %s", exc)
            return {}
        if sensor is None:
            return {}
        return {
            "customer": sensor.owner.name,
            "customer_address": sensor.owner.address or "",
            "dut_model": f"{sensor.model.maker} {sensor.model.model}",
            "dut_serial": sensor.serial,
        }

    def reference(self, identifier: str) -> Any:
        """The reference standard `identifier` on record, or None."""
        if self.lab is None:
            return None
        try:
            return next((r for r in self.lab.references() if r.identifier == identifier), None)
        except RecordsInputError as exc:
            log.warning("reference standards not read: %s", exc)
            return None

    def finish_later(
        self,
        service: RunService,
        prepared: PreparedRun,
        finished: Finished,
        done: Callable[[str], None],
    ) -> bool:
        """Finish a run through the run service on the records' thread (it indexes the run,
        verifying every file of its folder: `RunService.finish`); `done(its report)` is called
        on the GUI thread afterwards. False (and nothing done) when the run used no records."""
        if not prepared.records or finished.record.run_id is None:
            return False

        def finish() -> str:
            return service.finish(prepared, finished).index_note or ""

        self._jobs.append((self._pool.submit(finish), done))
        self._timer.start()
        return True

    def wait_jobs(self, timeout_s: float = 60.0) -> None:
        """Block until every indexing job is done and reported (tests)."""
        for future, _done in list(self._jobs):
            future.result(timeout=timeout_s)
        self._poll()
