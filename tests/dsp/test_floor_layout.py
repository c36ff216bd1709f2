"""The floor and harmonic bins of each line (dsp.spectral._floor_layout) against their
definition written out bin by bin (the vectorised layout must pick exactly the same bins)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from dsp.spectral import FLOOR_HALF_WIDTH_BINS, HARMONICS, _floor_layout


def _by_definition(
    bins: np.ndarray, period_samples: int
) -> tuple[list[list[int]], list[list[int]]]:
    n_bins = period_samples // 2 + 1

    def fold(b: int) -> int:
        b %= period_samples
        return period_samples - b if b > period_samples // 2 else b

    lines = {int(b) for b in bins}
    harmonics = {fold(h * int(b)) for b in bins for h in HARMONICS}
    free = [b for b in range(n_bins) if b not in lines | harmonics | {0}]
    if not free:
        free = [b for b in range(1, n_bins) if b not in lines]
    floors = []
    for b in bins:
        near = [f for f in free if abs(f - int(b)) <= FLOOR_HALF_WIDTH_BINS]
        if len(near) < 4:  # the nearest free bins instead (ties broken either way)
            nearest = sorted(free, key=lambda f: abs(f - int(b)))
            near = nearest[: min(2 * FLOOR_HALF_WIDTH_BINS, len(free))]
        floors.append(near)
    own = [sorted({fold(h * int(b)) for h in HARMONICS} - lines - {0}) for b in bins]
    return floors, own


@settings(max_examples=40, deadline=None)
@given(st.data())
def test_floor_layout_equals_its_definition(data: st.DataObject) -> None:
    period = data.draw(st.integers(16, 2000))
    bins = np.array(
        sorted(data.draw(st.sets(st.integers(1, period // 2 - 1), min_size=1, max_size=40))),
        dtype=np.int64,
    )
    floors, own = _floor_layout(bins, period)
    want_floors, want_own = _by_definition(bins, period)
    for line, got, want in zip(bins, floors, want_floors, strict=True):
        # the same distances from the line (which of two equidistant bins is free to differ)
        assert sorted(abs(got - line).tolist()) == sorted(abs(f - int(line)) for f in want)
        if all(abs(f - int(line)) <= FLOOR_HALF_WIDTH_BINS for f in want) and len(want) >= 4:
            assert got.tolist() == want
    assert [h.tolist() for h in own] == want_own


def test_floor_layout_of_the_piezo_preset_period() -> None:
    """The live run's layout (2 s at 51.2 kS/s): the 12 free bins each side of 100."""
    floors, own = _floor_layout(np.array([100, 1000]), 102400)
    assert floors[0].tolist() == [b for b in range(88, 113) if b not in (100,)]
    assert own[0].tolist() == [200, 300, 400, 500]
    assert own[1].tolist() == [2000, 3000, 4000, 5000]
