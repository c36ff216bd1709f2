"""What the Run tab's live plots show of a period and of an estimate, computed off the GUI thread.

The run worker (`app.gui.worker.RunWorker`) makes these views on its own thread as the events
arrive: the period decimated to at most 2 points per pixel column (min/max, so no peak is
lost), its spectra in dB decimated per column of the logarithmic frequency axis, the peaks the
input meters show, and the characteristic with its U. The GUI thread only hands the points to
pyqtgraph: a 2 s period at 51.2 kS/s (102 400 samples a channel, 51 200 spectral bins) costs
the GUI thread no more than a short one (SPEC s.11: no work over 50 ms on the Qt main thread).
Pure numpy; volts, hertz, dB re 1 V, percent and degrees as the names say.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from app import formatting as fmt
from dsp.calibration import Results
from dsp.characteristic import Characteristic
from dsp.characteristic import characteristic as dsp_characteristic
from dsp.multisine import Plan
from dsp.spectral import period_spectrum

MIN_COLUMNS = 200  # pixel columns a period is decimated to at the least (plot not shown yet)
DB_FLOOR = 1e-12  # V added before the dB: an empty bin reads -240 dB, never -inf
SHOWN_DB_SPAN = 160.0  # dB below the highest bin the spectrum's y axis reaches at most


def peak_decimated(x: np.ndarray, y: np.ndarray, columns: int) -> tuple[np.ndarray, np.ndarray]:
    """`y` over uniformly spaced `x` as at most 2 points per column (each column's minimum and
    maximum, in order), so a trace drawn `columns` pixels wide loses no peak."""
    n = y.size
    per = n // max(1, columns)
    if per < 4:
        return x, y
    used = per * (n // per)
    blocks = y[:used].reshape(-1, per)
    low, high = blocks.argmin(axis=1), blocks.argmax(axis=1)
    first = np.minimum(low, high) + np.arange(blocks.shape[0]) * per
    second = np.maximum(low, high) + np.arange(blocks.shape[0]) * per
    index = np.column_stack([first, second]).ravel()
    return x[index], y[index]


def log_decimated(f: np.ndarray, y: np.ndarray, columns: int) -> tuple[np.ndarray, np.ndarray]:
    """`y` (several rows) over increasing positive frequencies `f` (Hz), drawn on a logarithmic
    axis `columns` pixels wide, as 2 points per column that holds any bin (the column's
    minimum then maximum, at the column's geometric centre; a column of one bin keeps it where
    it is): the low decades keep every bin, the top decade is thinned, no peak is lost.
    Returns (frequencies, rows) with one frequency array for all rows."""
    rows = np.atleast_2d(y)
    if f.size <= 2 * columns or f[0] <= 0:
        return f, rows
    logf = np.log(f)
    column = np.minimum(
        ((logf - logf[0]) / (logf[-1] - logf[0]) * columns).astype(np.int64), columns - 1
    )
    starts = np.flatnonzero(np.diff(column, prepend=-1))
    ends = np.append(starts[1:], f.size)
    centre = np.where(ends - starts == 1, f[starts], np.sqrt(f[starts] * f[ends - 1]))
    low = np.minimum.reduceat(rows, starts, axis=1)
    high = np.maximum.reduceat(rows, starts, axis=1)
    shown = np.empty((rows.shape[0], 2 * starts.size))
    shown[:, 0::2], shown[:, 1::2] = low, high
    return np.repeat(centre, 2), shown


@dataclass(frozen=True)
class PeriodView:
    """One period as drawn: each channel's decimated trace (s, V), both spectra decimated on
    the log axis (Hz, dB re 1 V), the plan's lines on the reference spectrum (None when the
    period is not the plan's), the y ranges the plots follow, the channels' peaks (V) for the
    meters, and the period's length (samples) and rate (Hz) for the x ranges."""

    reference: tuple[np.ndarray, np.ndarray]
    dut: tuple[np.ndarray, np.ndarray]
    spectrum_hz: np.ndarray
    spectra_db: np.ndarray  # (2, points): reference, DUT
    lines: tuple[np.ndarray, np.ndarray] | None
    wave_range_v: tuple[float, float]
    spectrum_range_db: tuple[float, float]
    peaks_v: Mapping[str, float]
    samples: int
    sample_rate_hz: float


def period_view(reference: np.ndarray, dut: np.ndarray, plan: Plan, columns: int) -> PeriodView:
    """What the live plots draw of one period of `reference` and `dut` (V) read on `plan`'s
    rate, on plots `columns` pixels wide."""
    columns = max(MIN_COLUMNS, int(columns))
    fs = plan.sample_rate_hz
    n = reference.size
    t = np.arange(n) / fs
    both = np.vstack([reference, dut])
    wave_range = (float(both.min()), float(both.max())) if n else (math.nan, math.nan)
    spectra = np.abs(period_spectrum(both)) + DB_FLOOR
    lines = None
    if n == plan.period_samples:
        lines = (np.asarray(plan.frequencies_hz, dtype=float), 20 * np.log10(spectra[0, plan.bins]))
    f = np.arange(spectra.shape[1]) * fs / max(n, 1)
    db = 20 * np.log10(spectra[:, 1:])
    spectrum_hz, spectra_db = log_decimated(f[1:], db, columns)
    if db.size:
        top = float(db.max())
        spectrum_range = (max(float(db.min()), top - SHOWN_DB_SPAN), top)
    else:
        spectrum_range = (math.nan, math.nan)
    return PeriodView(
        reference=peak_decimated(t, reference, columns),
        dut=peak_decimated(t, dut, columns),
        spectrum_hz=spectrum_hz,
        spectra_db=spectra_db,
        lines=lines,
        wave_range_v=wave_range,
        spectrum_range_db=spectrum_range,
        peaks_v={
            "reference": float(np.max(np.abs(reference))) if n else 0.0,
            "dut": float(np.max(np.abs(dut))) if dut.size else 0.0,
        },
        samples=n,
        sample_rate_hz=fs,
    )


def block_view(
    samples: np.ndarray, channels: tuple[str, ...], plan: Plan, columns: int
) -> PeriodView:
    """`period_view` of a block as read (channels in `channels` order): the reference and
    the run's own DUT ("dut", or in a run of several DUTs the first "dut.<position>"); in a
    run of several DUTs the peaks (V) of every channel too, by name (each DUT's meter)."""
    names = list(channels)
    view = period_view(
        samples[names.index("reference")], samples[names.index(own_dut(names))], plan, columns
    )
    if "dut" in names or not samples.shape[-1]:
        return view
    peaks = {name: float(np.max(np.abs(row))) for name, row in zip(names, samples, strict=True)}
    return dataclasses.replace(view, peaks_v={**peaks, **view.peaks_v})


def own_dut(channels: Sequence[str]) -> str:
    """The DUT channel a run's own estimate reads: "dut", else the first "dut.<position>"
    (app.procedure.stand_io's rule)."""
    if "dut" in channels:
        return "dut"
    return next((n for n in channels if n.startswith("dut.")), "dut")


def characteristic(results: Results) -> Characteristic:
    """dsp.characteristic's deviation, phase and their U (the numbers the certificate draws),
    with a U that is not stated drawn as 0."""
    c = dsp_characteristic(results)
    return dataclasses.replace(
        c,
        deviation_expanded_percent=np.nan_to_num(c.deviation_expanded_percent),
        phase_expanded_deg=np.nan_to_num(c.phase_expanded_deg),
    )


@dataclass(frozen=True)
class EstimateView:
    """The characteristic so far as drawn (`characteristic`), log10 of its frequencies (the
    error bars' x), the y ranges (%, degree) with U, and the coherence line the tab shows."""

    characteristic: Characteristic
    log_frequency: np.ndarray
    deviation_range: tuple[float, float]
    phase_range: tuple[float, float]
    coherence: str


def estimate_view(results: Results) -> EstimateView:
    """What the live deviation and phase plots and the coherence line show of `results`."""
    c = characteristic(results)
    f = c.frequency_hz
    if f.size:
        dev, u_dev = c.deviation_percent, c.deviation_expanded_percent
        phase, u_phase = c.phase_deg, c.phase_expanded_deg
        deviation_range = (float(np.nanmin(dev - u_dev)), float(np.nanmax(dev + u_dev)))
        phase_range = (float(np.nanmin(phase - u_phase)), float(np.nanmax(phase + u_phase)))
    else:
        deviation_range = phase_range = (math.nan, math.nan)
    defined = [ln for ln in results.lines if math.isfinite(ln.coherence)]
    if defined:
        worst = min(defined, key=lambda ln: ln.coherence)
        coherence = (
            f"coherence >= {worst.coherence:.4f} (lowest at {worst.nominal_frequency_hz:g} Hz)"
        )
    else:
        coherence = fmt.COHERENCE_NOT_AVAILABLE
    return EstimateView(c, np.log10(f), deviation_range, phase_range, coherence)
