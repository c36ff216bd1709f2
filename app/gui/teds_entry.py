"""The "Read TEDS" button: the DUT's IEEE 1451.4 TEDS read on the stand (the simulated DUT's
memory, or the DUT channel through NI-DAQmx: `app.stand.teds.open_port`, as `accelcal run --teds`),
off the GUI thread; the sensor with that TEDS identity is then looked up in the records and the
fields are filled as for a typed serial. A failed read says why at the serial field and leaves
entry by hand; an identity not on record fills nothing.
"""

from __future__ import annotations

import logging
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from PySide6.QtCore import QObject, QTimer
from PySide6.QtWidgets import QPushButton

from app.gui.field_marks import WARNING
from app.records.db.errors import RecordsInputError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TedsRead:
    """What was read: the identity ('manufacturer/model/version/serial') and the nominal
    sensitivity in mV/(m/s^2) (None: not an accelerometer template)."""

    identity: str
    sensitivity_mv_per_ms2: float | None


def read_teds(stand_file: Path | None, dut: str, seed: int, position: Any = None) -> TedsRead:
    """Read and decode the DUT's TEDS (worker thread): the stand's DUT channel, or with
    `position` (an app.stand.fixture.FixturePosition) that position's input (on the simulated
    stand, a simulated DUT of its own: seed offset by the position's name). TedsError /
    ConfigError / HardwareError say why it failed."""
    from app.stand import teds as teds_io
    from hardware.teds import decode

    port = teds_io.open_port(stand_file, dut, seed)
    if position is not None:
        if port.sim is not None:
            from app.stand.simulated import open_simulated

            offset = sum(ord(c) for c in position.name)
            port = teds_io.TedsPort(
                f"simulated stand, DUT {dut!r} at {position.name}",
                sim=open_simulated(dut, seed + offset),
            )
        else:
            port = teds_io.TedsPort(
                f"DUT input {position.physical}", physical_channel=position.physical
            )
    teds = decode(port.read())
    a = teds.accelerometer
    return TedsRead(teds.basic.identity, a.sensitivity_mv_per_ms2 if a is not None else None)


class TedsEntry(QObject):
    """The button and its read, one at a time."""

    def __init__(
        self, setup: Any, link: Any, field: Any = None, entry: Any = None, position: Any = None
    ) -> None:
        super().__init__(setup)
        self.setup, self.link = setup, link
        # the serial field and its look-up (None: the single DUT's), the fixture position
        self._field, self._entry, self.position = field, entry, position
        self.button = QPushButton("Read TEDS")
        self.button.setToolTip("Identify the DUT by its TEDS (IEEE 1451.4) and look it up")
        self.button.clicked.connect(self.read)
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="teds")
        self._future: Future | None = None
        self._timer = QTimer(self, interval=50)
        self._timer.timeout.connect(self._poll)
        self.last: TedsRead | None = None

    @property
    def field(self) -> Any:
        """The serial field the read fills."""
        return self._field if self._field is not None else self.setup.dut_id

    @property
    def entry(self) -> Any:
        """The field's look-up (app.gui.sensor_entry.SerialEntry)."""
        return self._entry if self._entry is not None else self.setup.serial_entry

    @property
    def busy(self) -> bool:
        return self._future is not None

    def read(self) -> None:
        """Start a read on the stand the Setup tab has (never while a run uses it)."""
        w = self.setup
        if self.busy or w.running:
            return
        self.last = None
        self.button.setEnabled(False)
        self.button.setText("Reading TEDS ...")
        w.field_marks.note(self.field, None)
        self._future = self._pool.submit(
            read_teds, w.stand_file, w.dut.currentText(), int(w.options.seed), self.position
        )
        self._timer.start()

    def wait(self, timeout_s: float = 30.0) -> None:
        """Block until the read is done and shown (tests)."""
        if self._future is not None:
            try:
                self._future.result(timeout=timeout_s)
            except Exception:  # shown by _poll
                pass
        self._poll()

    def _poll(self) -> None:
        future = self._future
        if future is None or not future.done():
            return
        self._future = None
        self._timer.stop()
        self.button.setEnabled(True)
        self.button.setText("Read TEDS")
        try:
            read = future.result()
        except Exception as exc:  # TEDS, stand file or hardware: said, entry by hand
            log.warning("TEDS not read: %s", exc)
            self.setup.field_marks.note(
                self.field,
                f"TEDS not read: {exc}; type or scan the serial instead",
                WARNING,
            )
            return
        self.last = read
        self.show(read)

    def show(self, read: TedsRead) -> None:
        """Look the identity up and fill as for a typed serial (GUI thread)."""
        w = self.setup
        nominal = (
            f", nominal {read.sensitivity_mv_per_ms2:.4g} mV/(m/s²) in its TEDS"
            if read.sensitivity_mv_per_ms2 is not None
            else ""
        )
        lab = self.link.lab
        if lab is None:
            w.field_marks.note(
                self.field,
                f"TEDS identity {read.identity}{nominal}; {self.link.describe()}: type the serial",
                WARNING,
            )
            return
        try:
            serial = lab.sensor_by_teds(read.identity).serial
            sensor = self.link.sensor(serial)  # with its model and owner
        except RecordsInputError as exc:
            w.field_marks.note(
                self.field,
                f"{exc}{nominal}; nothing filled in: type the serial or register the sensor",
                WARNING,
            )
            return
        self.field.setText(sensor.serial)
        self.entry.take(sensor, f"TEDS identity {read.identity}")

    def close(self) -> None:
        self._pool.shutdown(wait=False, cancel_futures=True)
