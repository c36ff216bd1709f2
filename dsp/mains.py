"""Lines and the mains harmonics (SPEC s.3; issue 32 point 3): which mains harmonic a bin
sits on, and the bins with every line on one moved one bin. Hz, bins."""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["mains_harmonic_of_bin", "mains_shifted_bins"]


def mains_harmonic_of_bin(
    m: int, resolution_hz: float, mains_frequency_hz: float, mains_harmonics: int
) -> int:
    """The mains harmonic h (1..mains_harmonics) within half a bin of bin m, 0 for none
    (SPEC s.3)."""
    for h in range(1, mains_harmonics + 1):
        if abs(h * mains_frequency_hz / resolution_hz - m) < 0.5:
            return h
    return 0


def mains_shifted_bins(
    bins: Sequence[int],
    resolution_hz: float,
    mains_frequency_hz: float = 50.0,
    mains_harmonics: int = 5,
) -> list[int]:
    """The bins with every one on a mains harmonic moved one bin (issue 32 point 3: the
    default plans keep their lines off the mains harmonics, where hum while driven cannot be
    told from the line; the hum's own bin is then free and measured). In order of frequency
    the moved lines go alternately up and down (50.5, 99.5, 200.5, 249.5 Hz on 0.5 Hz bins),
    so they do not all lean one way: the presets' predicted table displacement stays below
    the exact bins' (capacitive at 7 m/s^2: 3.77 mm peak, against 4.31 mm all up). Hz."""
    out = [int(m) for m in bins]
    taken = set(out)
    moved = 0
    for k in sorted(range(len(out)), key=lambda i: out[i]):
        m = out[k]
        if not mains_harmonic_of_bin(m, resolution_hz, mains_frequency_hz, mains_harmonics):
            continue
        step = 1 if moved % 2 == 0 else -1
        for target in (m + step, m - step):  # never onto another line or DC: else kept
            if target > 0 and target not in taken:
                taken.discard(m)
                taken.add(target)
                out[k] = target
                moved += 1
                break
    return out
