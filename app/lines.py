"""Line lists as people type them, shared by the CLI and the GUI."""

from __future__ import annotations

import math

from dsp import iso266


def parse_frequencies(text: str) -> list[float]:
    """'10,12.5,...,2500' -> the ISO 266 values in between; plain lists as given (Hz).

    ValueError says what is wrong (without naming the field: the caller does).
    """
    items = [item.strip() for item in text.split(",")]
    if not any(items):
        raise ValueError("no frequency given")
    for position, item in enumerate(items, start=1):
        if not item:
            raise ValueError(f"item {position} of {text.strip()!r} is empty")
    values: list[float | None] = []
    for item in items:
        if item in ("...", "…"):
            values.append(None)
            continue
        try:
            value = float(item)
        except ValueError:
            raise ValueError(f"{item!r} is not a number of Hz") from None
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{item!r}: a frequency must be a finite number > 0 Hz")
        values.append(value)
    out: list[float] = []
    for i, entry in enumerate(values):
        if entry is not None:
            if out and entry <= out[-1]:
                raise ValueError("values must increase")
            out.append(entry)
            continue
        low = values[i - 1] if i > 0 else None
        high = values[i + 1] if i < len(values) - 1 else None
        if low is None or high is None:
            raise ValueError("'...' must stand between two frequencies")
        out += [f for f in iso266.nominal_frequencies(low, high) if low < f < high]
    if not out:
        raise ValueError("no frequency given")
    return out
