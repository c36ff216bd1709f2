"""A type B component stated as a table against frequency: one value per frequency, each
holding over its third-octave-like band (edges at the geometric mean of neighbouring rows),
as a laboratory states a term per band where no power law describes it (a resonance).

In a stand file:

    [[component]]
    name = "transverse motion (rocking mode), above 2 kHz"
    kind = "transverse_motion"
    distribution = "standard"
    min_frequency_hz = 2236.1          # optional: the first band's lower edge
    table = [[2500.0, 0.0019], [3150.0, 0.0023], [4000.0, 0.0036]]   # Hz, value

expands into one Component per row ("<name> at <f> Hz"), `value` read per `distribution` as
for any component, applying from its band's lower edge to just below the next band's. The
first band starts at `min_frequency_hz` (default: a half step below the first row, the
geometric mean with the row that would come before it at the same spacing); the last ends at
`max_frequency_hz` (default: a half step above the last row).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from typing import Any

TABLE_KEY = "table"


def _rows(where: str, table: Any) -> list[tuple[float, float]]:
    """The table's (Hz, value) rows, checked: at least one, frequencies rising and > 0."""
    if not isinstance(table, Sequence) or isinstance(table, str) or not table:
        raise ValueError(f"{where}: table must be a non-empty list of [frequency_hz, value] rows")
    rows: list[tuple[float, float]] = []
    for i, row in enumerate(table, start=1):
        if (
            not isinstance(row, Sequence)
            or isinstance(row, str)
            or len(row) != 2
            or not all(isinstance(x, int | float) and not isinstance(x, bool) for x in row)
        ):
            raise ValueError(f"{where}: table row {i} must be [frequency_hz, value], got {row!r}")
        f, v = float(row[0]), float(row[1])
        if not (math.isfinite(f) and f > 0):
            raise ValueError(f"{where}: table row {i}: frequency must be finite and > 0 Hz")
        if rows and f <= rows[-1][0]:
            raise ValueError(f"{where}: table row {i}: frequencies must rise ({f:g} Hz)")
        rows.append((f, v))
    return rows


def _edges(rows: list[tuple[float, float]], low: Any, high: Any) -> list[float]:
    """Band edges (Hz): len(rows) + 1 values, rising."""
    f = [r[0] for r in rows]
    step = f[1] / f[0] if len(f) > 1 else 2.0 ** (1.0 / 3.0)
    last = f[-1] / f[-2] if len(f) > 1 else step
    inner = [math.sqrt(a * b) for a, b in itertools.pairwise(f)]
    lo = float(low) if low is not None else f[0] / math.sqrt(step)
    hi = float(high) if high is not None else f[-1] * math.sqrt(last)
    return [lo, *inner, hi]


def expand_table(entry: Any) -> list[Any]:
    """One component entry with a `table` as one entry per row (anything else: itself, for
    Component.from_dict to accept or refuse)."""
    if not isinstance(entry, Mapping) or TABLE_KEY not in entry:
        return [entry]
    name = entry.get("name")
    where = f"component {name!r}" if isinstance(name, str) and name else "component <unnamed>"
    if "value" in entry:
        raise ValueError(f"{where}: give either value or table, not both")
    for key in ("law", "law_frequency_hz", "law_exponent"):
        if key in entry:
            raise ValueError(f"{where}: {key} does not go with a table (one value per band)")
    rows = _rows(where, entry[TABLE_KEY])
    edges = _edges(rows, entry.get("min_frequency_hz"), entry.get("max_frequency_hz"))
    if edges[0] > rows[0][0] or edges[-1] < rows[-1][0]:
        raise ValueError(
            f"{where}: min_frequency_hz/max_frequency_hz must lie outside the table's rows"
        )
    base = {k: v for k, v in entry.items() if k not in (TABLE_KEY, "name")}
    out = []
    for i, (f, v) in enumerate(rows):
        last = i == len(rows) - 1
        out.append(
            {
                **base,
                "name": f"{name} at {f:g} Hz",
                "value": v,
                "min_frequency_hz": edges[i],
                # each band ends just below the next one's edge, so no frequency counts twice
                "max_frequency_hz": edges[i + 1] if last else math.nextafter(edges[i + 1], 0.0),
            }
        )
    return out
