"""The overall verdict, large and plain: PASS, FAIL or INDETERMINATE with its reasons.

The verdict is computed once (`app.procedure.verdict`, stored in results.json as `verdict` and
`verdict_reasons`); this only shows what the results or the stored record say.
"""

from __future__ import annotations

import html
from collections.abc import Mapping
from typing import Any

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QLabel, QSizePolicy, QVBoxLayout, QWidget

from app.gui.table_items import shown_unit
from app.procedure.verdict import FAIL, INDETERMINATE, PASS
from app.records.run_record import RunRecord, verdict_stated
from dsp.conformity import DECISION_RULE_SHORT

COLOURS: dict[str, str] = {PASS: "#1e8449", FAIL: "#c0392b", INDETERMINATE: "#b9770e"}
NOT_ASSESSED = "not assessed"


def verdict_of(
    results: Any = None, record: RunRecord | Mapping[str, Any] | None = None
) -> tuple[str, list[str]]:
    """(verdict, reasons) of a run: from its Results, else its stored record; NOT_ASSESSED
    when neither states one (an aborted run, a run from before verdicts)."""
    verdict = getattr(results, "verdict", None)
    reasons = list(getattr(results, "verdict_reasons", ()) or ())
    if verdict is None and record is not None:  # as the records read it
        stated, stored = (
            record.stated_verdict if isinstance(record, RunRecord) else verdict_stated(record)
        )
        verdict, reasons = stated, list(stored)
    return (str(verdict) if verdict else NOT_ASSESSED), reasons


class VerdictView(QWidget):
    """A large coloured word and its reasons under it."""

    def __init__(self) -> None:
        super().__init__()
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        self.word = QLabel()
        self.word.setAccessibleName("overall verdict")
        self.reasons = QLabel()
        self.reasons.setWordWrap(True)
        self.reasons.setTextFormat(Qt.TextFormat.RichText)
        self.reasons.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.reasons.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.reasons.setMinimumWidth(1)
        layout.addWidget(self.word)
        layout.addWidget(self.reasons)
        self.show_verdict(None)

    @property
    def verdict(self) -> str | None:
        return self._verdict

    def show_verdict(self, verdict: str | None, reasons: list[str] | tuple[str, ...] = ()) -> None:
        """Show `verdict` (None: nothing shown) with its reasons."""
        self._verdict = verdict
        self.setVisible(verdict is not None)
        if verdict is None:
            self.word.setText("")
            self.reasons.setText("")
            return
        colour = COLOURS.get(verdict, "#555555")
        self.word.setText(verdict if verdict in COLOURS else f"Verdict {verdict}")
        self.word.setStyleSheet(
            f"font-size: 30px; font-weight: bold; color: white; background: {colour}; "
            "padding: 4px 16px; border-radius: 4px"
        )
        self.word.setSizePolicy(QSizePolicy.Policy.Maximum, QSizePolicy.Policy.Fixed)
        self.word.setToolTip(f"Overall verdict by {DECISION_RULE_SHORT}")
        if reasons:
            self.reasons.setText(
                "<ul style='margin:0'>"
                + "".join(f"<li>{html.escape(shown_unit(r))}</li>" for r in reasons)
                + "</ul>"
            )
        else:
            self.reasons.setText("every check passed" if verdict == PASS else "")
