"""Coverage of the one-period (LPM) estimator against the best linear approximation (BLA) of a
DUT with a stated nonlinearity (issue 32 point 4 and its acceptance).

Each run plays one random-phase realisation of the DUT's preset plan (5 m/s^2 per line) on a
fresh simulated stand (no systematic deviations, no mains hum: the estimator alone is tested):
a raised-cosine fade-in of 0.5 s, then one analysed period, the start-up transient left to the
LPM. The analysis is the product's: dsp.lpm_record.record_estimate on that period (what
`accelcal run --estimator lpm` and `analyze` call), which measures the distortion at the
detection bins and states the BLA, or a blocking warning naming the lines.

The truth is the BLA of the simulated DUT for this excitation class, exact at the sample
instants: (H_dut(f) + c3 beta_k H_cubic(f) H_mid(f)) / (H_ref(f) g_ref), with H_dut, H_ref,
H_mid the stand's sampled responses to the drive (H_mid: the table motion sampled mid-hold,
which the simulator cubes), H_cubic the response of the DUT's cubic path
(its dynamics behind the ZOH the simulator uses), c3 the DUT's cubic coefficient and
beta_k = 0.75 |A_k|^2 + 1.5 sum_{m != k} |A_m|^2 the phase-independent (Bussgang) gain of the
cubic at line k for the table amplitudes A (peak, m/s^2) as played (the exciter compresses
them by about 1 %: taken from the reference channel, whose noise is 1e-5 of the line). The
DUT "mems-cubic" (sim.models) has a cubic of 0.6 % of the signal (rms of the cubic term over
the linear term's) at this plan's level.

Coverage per line: |Re(H/H_BLA - 1)| <= k u (magnitude) and |Im(H/H_BLA - 1)| <= k u_phase
(phase), k = Student t at 95.45 % for the stated dof, counted over the runs in which the line
is stated (no blocking warning); Clopper-Pearson 95 % intervals. The same records analysed by
the plain LPM (no distortion handling) are shown beside it, as before issue 32.
Acceptance: 93-97.5 % at every stated line over 400 runs, or PASS blocked naming the distortion.

With periods=P (P > 16, dsp.lpm_record.WHOLE_RECORD_PERIODS) each run records P periods after
the fade-in and analyses that record twice: whole (record_estimate, the record in memory) and as
`analyze` reads a recording that long (record_estimate_batches: a batch of periods at a time,
the spectra held within 12 bins of each period-grid bin, the nonlinear fit on the free bins held):
coverage, distortion found and PASS blocked are shown for both, and the runs where they differ.

Run: python bench/nonlinear_coverage.py [RUNS] [DUT ...] [workers=W] [periods=P]
     (--smoke: 3 runs; default 400 runs of mems-cubic, 2 workers, one period; the lead's full
      run: python bench/nonlinear_coverage.py 400 mems-cubic capacitive piezo workers=2;
      issue 34's long records: python bench/nonlinear_coverage.py 100 mems-cubic piezo
      workers=2 periods=40)
"""

from __future__ import annotations

import logging
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from scipy import stats

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.records.warnings import blocking
from dsp import lpm, nonlinear
from dsp.calibration import LOW_SNR_DB
from dsp.crestfactor import synthesize
from dsp.lpm_record import WHOLE_RECORD_PERIODS, record_estimate, record_estimate_batches
from dsp.multisine import PRESETS, Line, Plan, fade_envelope
from hardware.interfaces import DaqConfig, InputChannel, OutputChannel
from sim.models import DUT_CATALOGUE, AdcModel, StandModel, plan_preset_for
from sim.stand import SimulatedStand

log = logging.getLogger("nonlinear_coverage")
LEVEL_MS2 = 5.0
FADE_S = 0.5
RANGES_V = (0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0)
P_STATED = 0.9545
MIN_SNR_DB = LOW_SNR_DB  # a run blocks a line under it ("low SNR", app/records/warnings.py)


def _range(peak_v: float) -> float:
    return next((r for r in RANGES_V if r >= 1.5 * peak_v), RANGES_V[-1])


def run_once(args: tuple[str, int, int]) -> dict[str, np.ndarray | bool | float]:
    """One run: hits per line of the product's estimator and of the plain LPM (one period), or
    of the whole record's and the batched analysis (`periods` > WHOLE_RECORD_PERIODS)."""
    dut, seed, periods = args
    preset = PRESETS[plan_preset_for(dut)]
    fs, n = preset.sample_rate_hz, preset.period_samples
    freqs = np.array(preset.nominal_frequencies_hz)
    bins = np.rint(freqs * n / fs).astype(np.int64)
    rng = np.random.default_rng([seed, 32])
    phases = rng.uniform(0, 2 * np.pi, freqs.size)
    model = StandModel(adc=AdcModel(hum_v=()))
    stand = SimulatedStand(dut, model=model, seed=seed, systematic=False)
    block = round(FADE_S * fs)
    amplitudes = np.full(freqs.size, LEVEL_MS2)
    peak = float(np.max(np.abs(synthesize(bins, amplitudes, phases, n))))
    dut_peak = peak * stand.dut.sensitivity_mv_per_ms2 * 1e-3 * 1.3
    ref_peak = peak * model.reference.sensitivity_mv_per_ms2 * 1e-3 * model.reference_gain
    config = DaqConfig(
        fs,
        block,
        OutputChannel("sim/ao0", 10.0),
        (
            InputChannel("reference", "sim/ai0", _range(ref_peak)),
            InputChannel("dut", "sim/ai1", _range(dut_peak)),
        ),
    )
    stand.configure(config)
    f = bins * fs / n
    response = stand.table_response(f)
    drive_amplitudes = amplitudes / np.abs(response)
    drive = synthesize(bins, drive_amplitudes, phases - np.angle(response), n)
    played = np.concatenate(
        [drive[:block] * fade_envelope(block, 1, "in"), np.roll(np.tile(drive, periods), -block)]
    )
    chunks = played.reshape(-1, block)
    out = []
    stand.start(chunks[0])
    for i in range(chunks.shape[0]):
        out.append(stand.read_period())
        if i + 1 < chunks.shape[0]:
            stand.write_period(chunks[i + 1])
    stand.stop()
    data = np.hstack(out)[:, block:]

    lines = tuple(
        Line(float(f0), float(fk), int(b), LEVEL_MS2, float(p))
        for f0, fk, b, p in zip(freqs, f, bins, phases, strict=True)
    )
    plan = Plan(fs, n, lines, preset.reference_frequency_hz)
    ref_blocks, dut_blocks = data[0].reshape(periods, n), data[1].reshape(periods, n)
    record = record_estimate(ref_blocks, dut_blocks, plan)

    chain = stand._chain  # the exact sampled model: the truth, never shown to the estimator
    # the table's line amplitudes (m/s^2 peak) as played (the exciter compresses them a
    # little): the reference's line values over its sensor and conditioning (noise 1e-5)
    per_ms2 = model.reference.model().response(f) * model.reference_gain
    table = record.lpm.reference_amplitude_v / np.abs(per_ms2)
    power = table**2
    beta = 0.75 * power + 1.5 * (power.sum() - power)
    linear = chain.discrete_response("dut", f, fs)
    cubic = stand.dut.cubic_per_ms2_sq
    if cubic and stand._cubic is not None:
        h_mid = chain.discrete_response("cubic_input", f, fs)  # the cubic's input, mid-hold
        linear = linear + cubic * beta * stand._cubic.discrete_response(f, fs) * h_mid
    truth = linear / (chain.discrete_response("reference", f, fs) * model.reference_gain)

    labels = [line.label for line in plan.lines]
    e = record.estimate
    assert e.nonlinear is not None
    blocked = bool(blocking(nonlinear.warnings(e.nonlinear, labels, e.relative_type_a)))
    mag, ph = _hits(e.response, e.relative_type_a, e.phase_type_a_rad, e.dof, truth)
    if periods == 1:
        plain = lpm.estimate(data[0], data[1], bins, excluded_bins=_mains(plan))
        mag0, ph0 = _hits(
            plain.response, plain.relative_type_a, plain.phase_type_a_rad, plain.dof, truth
        )
        blocked0, found0 = blocked, bool(e.nonlinear.found)
    else:  # the record as `analyze` reads a recording this long: a batch of periods at a time
        batches = (
            (ref_blocks[a : a + 16], dut_blocks[a : a + 16], None) for a in range(0, periods, 16)
        )
        streamed = record_estimate_batches(batches, periods, plan).estimate
        assert streamed.nonlinear is not None
        mag0, ph0 = _hits(
            streamed.response,
            streamed.relative_type_a,
            streamed.phase_type_a_rad,
            streamed.dof,
            truth,
        )
        blocked0 = bool(
            blocking(nonlinear.warnings(streamed.nonlinear, labels, streamed.relative_type_a))
        )
        found0 = bool(streamed.nonlinear.found)
    nl = record.nonlinear
    assert nl is not None
    return {
        "freqs": freqs,
        "mag": mag,
        "ph": ph,
        "mag0": mag0,
        "ph0": ph0,
        "blocked": blocked,
        "blocked0": blocked0,
        "found": nl.found,
        "found0": found0,
        "fraction": nl.fraction,
        "u": e.relative_type_a,
        "err": np.abs(e.response / truth - 1.0),
        "snr": np.asarray(e.dut_snr_db, dtype=float),
    }


def _mains(plan: Plan) -> set[int]:
    return lpm.mains_bins(
        plan.resolution_hz,
        plan.period_samples // 2 + 1,
        plan.mains_frequency_hz,
        plan.mains_harmonics,
    )


def _hits(response, u_mag, u_phase, dof, truth) -> tuple[np.ndarray, np.ndarray]:
    k = stats.t.ppf(0.5 + P_STATED / 2, dof)
    err = response / truth - 1.0
    return np.abs(err.real) <= k * u_mag, np.abs(err.imag) <= k * u_phase


def interval(hits: int, count: int) -> tuple[float, float]:
    """Clopper-Pearson 95 % interval of a proportion (percent)."""
    if count == 0:
        return float("nan"), float("nan")
    lo = stats.beta.ppf(0.025, hits, count - hits + 1) if hits > 0 else 0.0
    hi = stats.beta.ppf(0.975, hits + 1, count - hits) if hits < count else 1.0
    return 100 * float(lo), 100 * float(hi)


def report(dut: str, runs: int, workers: int, periods: int = 1) -> list[str]:
    """The markdown rows for one DUT (`periods` > 1: the whole record against the batches)."""
    t0 = time.perf_counter()
    args = [(dut, seed, periods) for seed in range(runs)]
    if workers > 1:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            results = list(pool.map(run_once, args, chunksize=4))
    else:
        results = [run_once(a) for a in args]
    elapsed = time.perf_counter() - t0
    freqs = np.asarray(results[0]["freqs"])
    stated = [r for r in results if not r["blocked"]]
    blocked = runs - len(stated)
    found = sum(bool(r["found"]) for r in results)
    fraction = np.median([float(r["fraction"]) for r in results])
    rows = [
        f"{dut}: {runs} runs of {periods} period(s) in {elapsed:.0f} s; distortion found in "
        f"{found}, PASS blocked in {blocked}; median measured distortion {100 * fraction:.3f} % "
        "of the signal",
        "",
        "| line | stated: magnitude (95 % CI) | phase (95 % CI) | plain LPM magnitude / phase "
        "| median u | median abs error | median DUT SNR (runs under 20 dB: blocked) |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    if periods > 1:
        found0 = sum(bool(r["found0"]) for r in results)
        blocked0 = sum(bool(r["blocked0"]) for r in results)
        differ = sum(bool(r["found0"]) != bool(r["found"]) for r in results)
        lo, hi = interval(found, runs)
        lo0, hi0 = interval(found0, runs)
        rows[0] = (
            f"{dut}: {runs} runs of {periods} periods in {elapsed:.0f} s; median measured "
            f"distortion {100 * fraction:.3f} % of the signal. Distortion found: whole record "
            f"{found} ({lo:.0f}-{hi:.0f} %), batches {found0} ({lo0:.0f}-{hi0:.0f} %), "
            f"differing in {differ} run(s); PASS blocked: whole {blocked}, batches {blocked0}"
        )
        rows[2] = (
            "| line | whole record: magnitude (95 % CI) | phase (95 % CI) | batches: magnitude "
            "(95 % CI) / phase (95 % CI) | median u | median abs error | median DUT SNR "
            "(runs under 20 dB: blocked) |"
        )
    worst = [100.0, 0.0]
    for k, f in enumerate(freqs):
        cells = []
        # a line under 20 dB SNR is blocked by the run ("low SNR"): not stated as PASS
        here = [r for r in stated if np.asarray(r["snr"])[k] >= MIN_SNR_DB]
        count = len(here)
        for key in ("mag", "ph"):
            hits = int(sum(bool(np.asarray(r[key])[k]) for r in here))
            lo, hi = interval(hits, count)
            share = 100 * hits / count if count else float("nan")
            if count:
                worst = [min(worst[0], share), max(worst[1], share)]
            cells.append(f"{share:.1f} ({lo:.1f}-{hi:.1f})")
        if periods > 1:  # the batches' coverage over the runs they state
            kept = [
                r for r in results if not r["blocked0"] and np.asarray(r["snr"])[k] >= MIN_SNR_DB
            ]
            shown = []
            for key in ("mag0", "ph0"):
                hits = int(sum(bool(np.asarray(r[key])[k]) for r in kept))
                lo, hi = interval(hits, len(kept))
                share = 100 * hits / len(kept) if kept else float("nan")
                shown.append(f"{share:.1f} ({lo:.1f}-{hi:.1f})")
            plain_cell = " / ".join(shown)
        else:
            plain = [
                100 * np.mean([np.asarray(r[key])[k] for r in results]) for key in ("mag0", "ph0")
            ]
            plain_cell = f"{plain[0]:.1f} / {plain[1]:.1f}"
        u = 100 * np.median([np.asarray(r["u"])[k] for r in results])
        err = 100 * np.median([np.asarray(r["err"])[k] for r in results])
        snr = np.array([np.asarray(r["snr"])[k] for r in results])
        rows.append(
            f"| {f:g} Hz | {cells[0]} | {cells[1]} | {plain_cell} | "
            f"{u:.4f} % | {err:.4f} % | {np.median(snr):.1f} dB ({int(np.sum(snr < MIN_SNR_DB))}) |"
        )
    rows.append("")
    rows.append(
        f"stated lines over {len(stated)} runs not blocked (less a line's runs under "
        f"{MIN_SNR_DB:g} dB SNR): coverage {worst[0]:.1f}-{worst[1]:.1f} % "
        "(acceptance 93-97.5 % at every line over 400 runs, or PASS blocked)"
    )
    return rows


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    options = dict(a.split("=", 1) for a in sys.argv[1:] if "=" in a)
    args = [a for a in sys.argv[1:] if "=" not in a]
    if args and args[0] == "--smoke":  # a few seconds, figures not meaningful
        args, options = ["3", "mems-cubic"], {"workers": "1"}
    try:
        runs = int(args[0]) if args else 400
        workers = int(options.get("workers", 2))
        periods = int(options.get("periods", 1))
    except ValueError:
        log.error("RUNS, workers=W and periods=P must be whole numbers")
        raise SystemExit(2) from None
    if not (periods == 1 or periods > WHOLE_RECORD_PERIODS):
        log.error(
            "periods=P: 1, or more than %d (a record analysed in batches)", WHOLE_RECORD_PERIODS
        )
        raise SystemExit(2)
    duts = args[1:] or ["mems-cubic"]
    unknown = [d for d in duts if d not in DUT_CATALOGUE]
    if unknown:
        log.error("DUT: unknown %s; the catalogue has %s", unknown, ", ".join(DUT_CATALOGUE))
        raise SystemExit(2)
    for dut in duts:
        for row in report(dut, runs, workers, periods):
            log.info(row)


if __name__ == "__main__":
    main()
