"""The fixture's positions on the Setup tab (issue 36): when the stand file has a [fixture], the
DUT box lists each position (name, distance from the reference axis, mass limit) with a serial
field, looked up in the records as the single DUT's serial field is (`SerialEntry`), and a Read
TEDS button of its own (`TedsEntry` on that position's input). A position whose serial is empty
is not run; the positions with a serial are the run's members (`MemberChoice`), in the
fixture's order. Nothing here computes: the run service checks the members when the run starts.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from PySide6.QtWidgets import QFormLayout, QGroupBox, QLabel, QLineEdit, QVBoxLayout, QWidget

from app.gui.sensor_entry import SerialEntry
from app.gui.teds_entry import TedsEntry
from app.io.vocabulary import Mode

if TYPE_CHECKING:
    from app.gui.field_marks import FieldMarks
    from app.procedure.batch import MemberChoice
    from app.stand.fixture import Fixture, FixturePosition


@dataclass
class PositionRow:
    """One position's row: the position, its serial field, its look-up and its TEDS read
    (None: a triaxial position, listed but not run here)."""

    position: FixturePosition
    serial: QLineEdit
    entry: SerialEntry | None
    teds: TedsEntry | None


def position_label(position: FixturePosition) -> str:
    """'A: 15 mm, up to 0.1 kg' (the distance from the reference axis, the mass limit)."""
    limit = (
        f"up to {position.mass_limit_kg:g} kg"
        if position.mass_limit_kg is not None
        else "the fixture's limit"
    )
    return f"{position.name}: {position.distance_mm:g} mm, {limit}"


class FixtureEntry:
    """The positions box (`widget`: empty and hidden on a stand without a fixture)."""

    def __init__(self, setup: Any, link: Any, marks: FieldMarks) -> None:
        self.setup, self.link, self.marks = setup, link, marks
        self.fixture: Fixture | None = None
        self.rows: list[PositionRow] = []
        self.widget = QWidget()
        self._layout = QVBoxLayout(self.widget)
        self._layout.setContentsMargins(0, 0, 0, 0)
        self.box: QGroupBox | None = None
        self.widget.setVisible(False)

    def show_fixture(self, fixture: Fixture | None) -> None:
        """List the positions of `fixture` (None: no box), every serial empty."""
        self.close()
        for row in self.rows:
            self.marks.forget(row.serial)
        self.rows = []
        if self.box is not None:
            self._layout.removeWidget(self.box)
            self.box.deleteLater()
            self.box = None
        self.fixture = fixture
        self.widget.setVisible(fixture is not None)
        if fixture is None:
            return
        self.box = QGroupBox(f"DUTs on the fixture: {fixture.name}")
        form = QFormLayout(self.box)
        form.setRowWrapPolicy(QFormLayout.RowWrapPolicy.WrapLongRows)
        note = QLabel("One run excites every DUT with a serial; an empty position is not run.")
        note.setWordWrap(True)
        form.addRow(note)
        for position in fixture.positions:
            serial = QLineEdit()
            serial.setAccessibleName(f"serial at position {position.name}")
            form.addRow(position_label(position), serial)
            if position.axes:  # three inputs: the triaxial procedure's, not a batch member
                serial.setEnabled(False)
                serial.setPlaceholderText("triaxial position: not in a run of several DUTs")
                self.rows.append(PositionRow(position, serial, None, None))
                continue
            serial.setPlaceholderText("serial (scan or type; empty: not run)")
            entry = SerialEntry(self.setup, self.link, self.marks, serial)
            # a DUT on record offers its model's run templates, as the single serial does
            entry.sensor_changed.connect(self.setup.templates.show_for)
            teds = TedsEntry(self.setup, self.link, serial, entry, position)
            teds.button.setText(f"Read TEDS at {position.name}")
            teds.button.setToolTip(
                f"Identify the DUT at position {position.name} by its TEDS and look it up"
            )
            form.addRow("", teds.button)
            self.rows.append(PositionRow(position, serial, entry, teds))
        self._layout.addWidget(self.box)

    def show_for(self, setup: Any) -> None:
        """The positions of `setup`'s stand in place of its single DUT's serial and TEDS rows
        (a stand without a fixture: those rows as always)."""
        fixture = setup.config.fixture
        self.show_fixture(fixture)
        for field in (setup.dut_id, setup.teds.button):
            setup.dut_form.setRowVisible(field, fixture is None)
        if fixture is not None:
            self.marks.note(setup.dut_id, None)

    @property
    def active(self) -> bool:
        """The stand has a fixture: a run is of the DUTs at its positions."""
        return self.fixture is not None

    def members(self) -> list[MemberChoice]:
        """The positions with a serial, in the fixture's order."""
        from app.procedure.batch import MemberChoice

        return [
            MemberChoice(row.position.name, row.serial.text().strip())
            for row in self.rows
            if row.entry is not None and row.serial.text().strip()
        ]

    def problems(self, mode: str) -> list[str]:
        """Why the positions cannot run as they are (none without a fixture)."""
        if self.fixture is None:
            return []
        out = []
        members = self.members()
        if not members:
            out.append("fixture: type or scan the serial of at least one position's DUT")
        serials = [m.serial for m in members]
        twice = sorted({s for s in serials if serials.count(s) > 1})
        if twice:
            out.append(f"fixture: serial {', '.join(twice)} at two positions")
        if mode != Mode.MULTISINE:
            out.append("mode: several DUTs in one run take the multisine only")
        return out

    def reset(self) -> None:
        """No serial at any position (the next batch)."""
        for row in self.rows:
            row.serial.clear()
            if row.entry is not None:
                row.entry.reset()

    def close(self) -> None:
        """The TEDS reads' pools end."""
        for row in self.rows:
            if row.teds is not None:
                row.teds.close()
