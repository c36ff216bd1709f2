"""The summary of an amplitude sweep (sweep-<id>.json beside its run folders): sensitivity
(mV/(m/s^2)) against frequency (Hz) and level (m/s^2 peak), linearity per line (%).

The one reader and writer of the file: app.procedure.sweep writes it, app.certificate reads it.
The JSON keeps the key order and layout written before this class existed.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from app.errors import Refusal
from app.records.run_folder import READ_ONLY_FILE, STATUS_COMPLETE


class SweepSummaryError(Refusal):
    """A sweep summary that cannot be read; the message names the file and why."""


@dataclass(frozen=True)
class SweepTable:
    """Sensitivity per level (rows) and frequency (columns), mV/(m/s^2), and linearity (%)."""

    frequencies_hz: tuple[float, ...]
    sensitivity_mv_per_ms2: tuple[tuple[float, ...], ...]
    linearity_percent: tuple[float, ...]
    reference_frequency_hz: float
    reference_linearity_percent: float
    worst_linearity_percent: float
    worst_linearity_frequency_hz: float


@dataclass(frozen=True)
class SweepSummary:
    """A sweep: its status, levels (m/s^2), run ids, why it stopped, and its table (None with
    fewer than two complete levels, or when read without it). `tabulated`: the file has a
    table (read or not)."""

    status: str
    levels_ms2: tuple[float, ...]
    run_ids: tuple[str, ...]
    abort_reason: str | None = None
    table: SweepTable | None = field(default=None)
    tabulated: bool = False

    def __post_init__(self) -> None:
        if self.table is not None and not self.tabulated:
            object.__setattr__(self, "tabulated", True)

    @property
    def complete(self) -> bool:
        """Every level completed and the table is there."""
        return self.status == STATUS_COMPLETE and self.tabulated

    def to_dict(self) -> dict[str, Any]:
        """The JSON object as written (key order kept)."""
        data: dict[str, Any] = {
            "status": str(self.status),
            "levels_ms2": list(self.levels_ms2),
            "run_ids": list(self.run_ids),
            "abort_reason": self.abort_reason,
        }
        t = self.table
        if t is not None:
            data.update(
                frequencies_hz=list(t.frequencies_hz),
                sensitivity_mv_per_ms2=[list(row) for row in t.sensitivity_mv_per_ms2],
                linearity_percent=list(t.linearity_percent),
                reference_frequency_hz=t.reference_frequency_hz,
                reference_linearity_percent=t.reference_linearity_percent,
                worst_linearity_percent=t.worst_linearity_percent,
                worst_linearity_frequency_hz=t.worst_linearity_frequency_hz,
            )
        return data

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_dict(cls, data: Any, with_table: bool = True) -> SweepSummary:
        """A summary from its JSON object (without its table: the head only, to check which
        runs it names first); SweepSummaryError names a malformed field."""
        if not isinstance(data, dict):
            raise SweepSummaryError("not a JSON object")
        try:
            table = None
            if with_table and "sensitivity_mv_per_ms2" in data:
                table = SweepTable(
                    frequencies_hz=tuple(float(f) for f in data["frequencies_hz"]),
                    sensitivity_mv_per_ms2=tuple(
                        tuple(float(v) for v in row) for row in data["sensitivity_mv_per_ms2"]
                    ),
                    linearity_percent=tuple(float(v) for v in data["linearity_percent"]),
                    reference_frequency_hz=float(data["reference_frequency_hz"]),
                    reference_linearity_percent=float(data["reference_linearity_percent"]),
                    worst_linearity_percent=float(data["worst_linearity_percent"]),
                    worst_linearity_frequency_hz=float(data["worst_linearity_frequency_hz"]),
                )
            return cls(
                status=str(data.get("status", "")),
                levels_ms2=tuple(float(v) for v in data.get("levels_ms2", ())),
                run_ids=tuple(str(r) for r in data.get("run_ids", ())),
                abort_reason=data.get("abort_reason"),
                table=table,
                tabulated="sensitivity_mv_per_ms2" in data,
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise SweepSummaryError(f"malformed sweep summary ({exc})") from None

    @classmethod
    def read(cls, path: Path, with_table: bool = True) -> SweepSummary:
        """The summary in `path` (see from_dict); SweepSummaryError('<path>: ...') when it
        cannot be read."""
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise SweepSummaryError(f"{path}: cannot be read ({exc})") from None
        try:
            summary = cls.from_dict(data, with_table)
        except SweepSummaryError as exc:
            raise SweepSummaryError(f"{path}: {exc}") from None
        return summary

    def write(self, path: Path) -> None:
        """Write the summary to `path` (a new temporary file of app.files.write_with),
        read-only like the run folders it sums up."""
        path.write_text(self.to_json(), encoding="utf-8")
        path.chmod(READ_ONLY_FILE)
