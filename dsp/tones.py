"""Tones beside the lines: content at non-excited bins that is not on a bin of its own (hum a
little off the mains frequency, while driven) and what it leaks onto each line (issue 32
point 3). Units: bins, volts (peak-scaled DFT magnitudes, dsp.spectral).

A stationary tone at the fractional bin nu, seen through the rectangular window of one period
(or of the average of several: the same factor at every bin), gives at an integer bin j

    |X_j| = |c| |sin(pi (j - nu))| / (pi |j - nu|) = S / |j - nu|,

with the same S = |c sin(pi nu)| / pi at every integer j. So two free bins locate the tone and
give its content at a line bin m, S / |m - nu|, exactly. A tone on a bin (nu integer: hum at
exactly the mains frequency, a harmonic of a line) has S = 0 and leaks onto no other bin. A
tone within `ON_LINE_BINS` of a line cannot be told from the line (its phase turns by less
than that fraction of a cycle per period): the line is then not separable.

Tones are found strongest first among the free bins over `DETECT_POWER` times the local
noise power (the median of the free bins' |X|^2 nearby over ln 2: exponential for
noise); noise alone passes with probability e^-16 per bin. Noise power is subtracted before a
tone is located, so noise is left to type A.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dsp.quantiles import median  # np.median imports numpy.ma (issue 34)

DETECT_POWER = 16.0  # a free bin this far over the noise power holds a tone
ON_LINE_BINS = 0.2  # a tone nearer a line than this (bins) is not separable from it
FLOOR_REACH = 32  # free bins each side whose median gives the local noise power
MAX_TONES = 64  # tones located per spectrum at most
FIT_REACH = 3  # free bins each side of a tone's peak that locate it


@dataclass(frozen=True)
class Tone:
    """A tone found at non-excited bins: fractional bin `position` nu and the complex constant
    C of the module docstring (X_j = C / (nu - j) at every integer bin j; V x bins); C = 0 for
    a tone on a bin (`peak_v` there)."""

    position: float
    c: complex
    peak_bin: int
    peak_v: float

    @property
    def amplitude(self) -> float:
        """|c|, the tone's own amplitude (V): 2 pi |C| / |e^(2 pi i nu) - 1| (its bin's value
        when it sits on a bin)."""
        sine = abs(math.sin(math.pi * self.position))
        if sine < 1e-6 or self.c == 0:
            return self.peak_v
        return abs(self.c) * math.pi / sine

    def spread(self, bins: np.ndarray) -> np.ndarray:
        """Its complex content at each of `bins` (V): C / (nu - j)."""
        if self.c == 0:
            return np.zeros(np.shape(bins), complex)
        distance = self.position - np.asarray(bins, dtype=float)
        safe = np.where(np.abs(distance) > 1e-9, distance, 1e-9)
        return self.c / safe

    def at(self, m: int) -> complex:
        """Its content at integer bin m (V), at most the tone's amplitude."""
        value = complex(self.spread(np.array([m]))[0])
        limit = self.amplitude
        return value if abs(value) <= limit else value / abs(value) * limit


@dataclass(frozen=True)
class LineLeak:
    """Per line (plan order): the tones' content at the line bin (V), the nearest tone's
    position (fractional bin; NaN: none found) and whether the line is separable from it."""

    leak_v: np.ndarray
    tone_bin: np.ndarray
    separable: np.ndarray


def free_bins(line_bins: np.ndarray, size: int) -> np.ndarray:
    """Bool mask over bins 0..size-1: True where no line sits (DC and Nyquist excluded)."""
    free = np.ones(size, dtype=bool)
    free[0] = False
    free[-1] = False
    free[np.asarray(line_bins, dtype=np.int64)] = False
    return free


def noise_power(spectrum: np.ndarray, free: np.ndarray, reach: int = FLOOR_REACH) -> np.ndarray:
    """Per bin, the local noise power (V^2) of the free bins: their |X|^2's median over the
    `reach` free bins each side divided by ln 2 (robust against the tones among them)."""
    index = np.flatnonzero(free)
    power = np.abs(spectrum[index]) ** 2
    out = np.zeros(spectrum.size)
    if index.size == 0:
        return out
    positions = np.searchsorted(index, np.arange(spectrum.size))
    # medians on a coarse grid of free-bin positions, then held (tones are sparse)
    step = max(1, reach // 2)
    anchors = range(0, index.size, step)
    medians = np.array(
        [median(power[max(0, a - reach) : a + reach + 1]) / math.log(2) for a in anchors]
    )
    slot = np.clip(np.rint(positions / step).astype(int), 0, len(anchors) - 1)
    out[:] = medians[slot]
    return out


def find_tones(spectrum: np.ndarray, line_bins: np.ndarray, most: int = MAX_TONES) -> list[Tone]:
    """The tones among the free bins of `spectrum` (complex, one-sided, V; module docstring),
    strongest first: each is fitted (`_fit`) to the free bins beside its peak, leaving the
    peak bin out (a tone on that bin, such as hum at exactly the mains frequency, adds there
    only), then taken off every free bin (both flanks: a line between them interrupts them),
    at most `most` tones."""
    x = np.asarray(spectrum, dtype=complex)
    free = free_bins(line_bins, x.size)
    floor = noise_power(x, free)
    threshold = DETECT_POWER * np.maximum(floor, 1e-300)
    residual = np.where(free, x, 0.0)
    index = np.flatnonzero(free)
    tones: list[Tone] = []
    seen: set[int] = set()
    while len(tones) < most:
        power = np.abs(residual) ** 2
        over = np.flatnonzero(power > threshold)
        if over.size == 0:
            break
        p = int(over[np.argmax(power[over])])
        tone = None if p in seen else _fit(p, residual, free, floor)
        seen.add(p)
        if tone is None:  # on its bin: no leak; the bin is done
            tones.append(Tone(float(p), 0j, p, float(abs(residual[p]))))
            residual[p] = 0.0
            continue
        tones.append(tone)
        residual[index] -= tone.spread(index)
    return tones


def _fit(p: int, x: np.ndarray, free: np.ndarray, floor: np.ndarray) -> Tone | None:
    """The off-bin tone peaking near free bin p from the free bins within FIT_REACH of it
    (p left out): X_j (nu - j) = C, least squares in the real nu and the complex C. None when
    no bin beside p holds more than noise (the tone sits on bin p)."""
    near = [
        j for j in range(p - FIT_REACH, p + FIT_REACH + 1) if j != p and 0 < j < x.size and free[j]
    ]
    if len(near) < 2 or max(abs(x[j]) ** 2 / max(floor[j], 1e-300) for j in near) < 4.0:
        return None
    j = np.asarray(near, dtype=float)
    xj = x[near]
    # unknowns (nu, Re C, Im C): Re/Im of X_j nu - C = j X_j
    a = np.zeros((2 * len(near), 3))
    a[0::2, 0], a[1::2, 0] = xj.real, xj.imag
    a[0::2, 1] = -1.0
    a[1::2, 2] = -1.0
    b = np.empty(2 * len(near))
    b[0::2], b[1::2] = (j * xj).real, (j * xj).imag
    solution, *_ = np.linalg.lstsq(a, b, rcond=None)
    nu, c = float(solution[0]), complex(solution[1], solution[2])
    if not (math.isfinite(nu) and abs(nu - p) <= FIT_REACH):
        return None
    tone = Tone(nu, c, p, float(abs(x[p])))
    # significance: the fitted flanks must hold DETECT_POWER noise powers between them (noise
    # alone in FIT_REACH bins each side reaches that with probability ~1e-3; a tone on bin p
    # has no flanks, and fitting its neighbours' noise must not invent one)
    if np.sum(np.abs(tone.spread(j)) ** 2) < DETECT_POWER * float(np.mean(floor[near])):
        return None
    return tone


def line_leak(spectrum: np.ndarray, line_bins: np.ndarray) -> LineLeak:
    """Each line's content from the tones beside it (V: the magnitude of their complex sum at
    the line bin) and whether the line is separable (no tone within ON_LINE_BINS of it)."""
    bins = np.asarray(line_bins, dtype=np.int64)
    tones = [t for t in find_tones(spectrum, bins) if t.c != 0]
    leak = np.zeros(bins.size)
    nearest = np.full(bins.size, np.nan)
    separable = np.ones(bins.size, dtype=bool)
    for k, m in enumerate(bins):
        total = 0j
        best = math.inf
        for tone in tones:
            distance = abs(int(m) - tone.position)
            if distance < ON_LINE_BINS:
                separable[k] = False
            total += tone.at(int(m))
            if distance < best:
                best, nearest[k] = distance, tone.position
        leak[k] = abs(total)
    return LineLeak(leak, nearest, separable)
