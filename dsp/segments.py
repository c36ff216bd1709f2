"""The seed paper's own protocol: a record split into L equal segments (seed section 2).

The seed splits its record (fs 6 kHz, 12000 samples) into L = 4, 8, 16 or 32 segments instead
of whole periods. A line off a segment's bin grid is evaluated at its exact frequency (leakage is
not removed: warned); lines whose nearest segment bins coincide cannot be separated and are
refused by name (at L = 32 the 10 Hz and 12.5 Hz lines share one 16 Hz bin).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dsp.errors import InputRefused
from dsp.spectral import dft_at


class SegmentError(InputRefused):
    """The record cannot be split as asked (lines not separable, too short)."""


def segment_plan(
    record_samples: int,
    segments: int,
    frequencies_hz: Sequence[float] | np.ndarray,
    labels: Sequence[str],
    sample_rate_hz: float,
) -> tuple[int, list[str]]:
    """Segment length in samples and warnings; SegmentError names unseparable lines."""
    if segments < 1:
        raise SegmentError(f"segments: must be >= 1, got {segments}")
    length = record_samples // segments
    if length < 2:
        raise SegmentError(f"segments: {segments} segments of a {record_samples}-sample record")
    warnings = []
    if record_samples % segments:
        warnings.append(
            f"segments: the last {record_samples % segments} sample(s) do not fill a segment "
            "and are not used"
        )
    resolution = sample_rate_hz / length
    nearest = [round(f / resolution) for f in frequencies_hz]
    owner: dict[int, str] = {}
    problems = []
    for label, b in zip(labels, nearest, strict=True):
        if b == 0:
            problems.append(
                f"line {label}: below the {resolution:g} Hz segment resolution (lands on DC)"
            )
        elif b in owner:
            problems.append(
                f"line {label}: shares the {b * resolution:g} Hz bin of line {owner[b]} at "
                f"{segments} segments ({resolution:g} Hz resolution); use fewer segments"
            )
        else:
            owner[b] = label
    if problems:
        raise SegmentError("; ".join(problems))
    off_grid = [
        label
        for label, f, b in zip(labels, frequencies_hz, nearest, strict=True)
        if not np.isclose(f, b * resolution, rtol=1e-9)
    ]
    if off_grid:
        warnings.append(
            f"segments: {len(off_grid)} line(s) off the {resolution:g} Hz segment grid, "
            f"evaluated at their exact frequency with leakage: {', '.join(off_grid)}"
        )
    return length, warnings


def segment_line_spectra(
    record_v: np.ndarray,
    segments: int,
    segment_samples: int,
    frequencies_hz: Sequence[float] | np.ndarray,
    sample_rate_hz: float,
) -> np.ndarray:
    """Peak-scaled DFT of each segment at the exact line frequencies, shape (segments, lines)."""
    blocks = np.asarray(record_v, dtype=float)[: segments * segment_samples]
    return dft_at(blocks.reshape(segments, segment_samples), frequencies_hz, sample_rate_hz)
