"""Coverage of the LPM's type A interval over the simulated stand with known truth (issue 26).

Each trial plays P = 3 random-phase realisations of a seed plan on a fresh simulated stand
(no systematic deviations, no mains hum: the estimator alone is tested; hum at a line is the
budget's own component, dsp.hum): a raised-cosine fade-in of 0.5 s, then the analysed
period(s) at once, the start-up transient left to the LPM. The truth is the stand's exact
sampled DUT/reference response (ZOH, skew and conditioning included) times the DUT's own
cubic term's best linear gain for that excitation. Coverage: |Re(H/H0 - 1)| <= k u (magnitude)
and |Im(H/H0 - 1)| <= k u (phase) with k = Student's t at 95.45 % for the stated dof.

The first realisation then runs three more periods: the periodic estimator (dsp.spectral) on
those three and the LPM on the same three as one record give the efficiency ratio
var(periodic)/var(LPM) from the observed errors on the same records.

Low frequencies: 0.4-8 Hz (ISO 266 from 0.4 Hz) on the long-stroke exciter, the grid `accelcal
run` builds for them (app.procedure.planning: dsp.lpm.design_grid, lines within 2 % of
nominal and inside 0.4-8 Hz, 22.15 s, 0.4 Hz at 0.406 Hz), the README's profile (1.5 m/s^2,
constant displacement below 3 Hz), one period after a 2.5 s fade-in, piezo DUT, P = 1.

Run: python bench/lpm_coverage.py [TRIALS] [DUT ...] [order=R] [bins=M]  (--smoke: 4)
     python bench/lpm_coverage.py low [TRIALS]               (default 1000 trials)
     (default 400 trials, piezo capacitive, order 2, 12 bins)
     python bench/lpm_coverage.py smoke                  (a few trials, seconds)
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

from app.procedure.planning import GRID_TOLERANCE, LONGEST_PERIOD_S
from dsp import iso266, lpm
from dsp.crestfactor import synthesize
from dsp.multisine import PRESETS, fade_envelope
from dsp.profiles import AmplitudeProfile, Profile
from dsp.spectral import SpectralAccumulator
from hardware.interfaces import DaqConfig, InputChannel, OutputChannel
from sim.models import EXCITER_CATALOGUE, AdcModel, StandModel
from sim.stand import SimulatedStand

log = logging.getLogger("lpm_coverage")
LEVEL_MS2 = 5.0
FADE_S = 0.5  # >= 4 cycles of the lowest line (10 Hz), a quarter of the 2 s period
RANGES_V = (0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0)
REALISATIONS = 3
SETTINGS = lpm.LpmSettings()  # replaced by order=R bins=M arguments
EXTRA_PERIODS = 3  # after the first analysed period of realisation 1, for the comparison


def _range(peak_v: float) -> float:
    return next((r for r in RANGES_V if r >= 1.5 * peak_v), RANGES_V[-1])


def _record(dut: str, seed: int, blocks: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """Fade in over one block, then `blocks` periods; (reference, DUT, truth, info)."""
    preset = PRESETS[dut]
    fs, n = preset.sample_rate_hz, preset.period_samples
    freqs = np.array(preset.nominal_frequencies_hz)
    bins = np.rint(freqs * n / fs).astype(np.int64)
    rng = np.random.default_rng([seed, 26])
    phases = rng.uniform(0, 2 * np.pi, freqs.size)
    model = StandModel(adc=AdcModel(hum_v=()))
    stand = SimulatedStand(dut, model=model, seed=seed, systematic=False)
    block = round(FADE_S * fs)
    assert n % block == 0
    acceleration = synthesize(bins, np.full(freqs.size, LEVEL_MS2), phases, n)
    peak = float(np.max(np.abs(acceleration)))
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
    response = stand.table_response(bins * fs / n)
    drive = synthesize(bins, LEVEL_MS2 / np.abs(response), phases - np.angle(response), n)
    played = np.concatenate([drive[:block] * fade_envelope(block, 1, "in"), np.tile(drive, blocks)])
    # the periodic part starts after the fade: shift so that it continues the fade's phase
    played[block:] = np.tile(np.roll(drive, -block), blocks)
    chunks = played.reshape(-1, block)
    out = []
    stand.start(chunks[0])
    for i in range(chunks.shape[0]):
        out.append(stand.read_period())
        if i + 1 < chunks.shape[0]:
            stand.write_period(chunks[i + 1])
    stand.stop()
    data = np.hstack(out)[:, block:]  # drop the fade block
    f = bins * fs / n
    chain = stand._chain  # the exact sampled model: the truth, never shown to the estimator
    truth = chain.discrete_response("dut", f, fs) / (
        chain.discrete_response("reference", f, fs) * model.reference_gain
    )
    c3 = stand.dut.cubic_per_ms2_sq
    sigma2 = np.sum(np.full(freqs.size, LEVEL_MS2) ** 2) / 2
    truth = truth * (1.0 + c3 * (3 * sigma2 - 0.75 * LEVEL_MS2**2))  # best linear gain
    return data[0], data[1], truth, {"bins": bins, "n": n, "freqs": freqs}


def _hits(est_response, u_mag, u_phase, dof, truth) -> tuple[np.ndarray, np.ndarray]:
    k = stats.t.ppf(0.5 + 0.9545 / 2, dof)
    err = est_response / truth - 1.0
    return np.abs(err.real) <= k * u_mag, np.abs(err.imag) <= k * u_phase


def trial(args: tuple[str, int, lpm.LpmSettings]) -> dict[str, np.ndarray]:
    """One trial: coverage hits at P = 1, 2, 3 and the errors of both estimators."""
    dut, seed, settings = args
    refs, duts = [], []
    first_extra = None
    truth = np.zeros(0)
    info: dict = {}
    for p in range(REALISATIONS):
        blocks = 1 + (EXTRA_PERIODS if p == 0 else 0)
        ref, dy, truth, info = _record(dut, seed * REALISATIONS + p, blocks)
        n = info["n"]
        refs.append(ref[:n])
        duts.append(dy[:n])
        if p == 0:
            first_extra = (ref[n:], dy[n:])
    bins = info["bins"]
    out: dict[str, np.ndarray] = {"freqs": info["freqs"]}
    for count in (1, 2, 3):
        e = lpm.estimate(np.array(refs[:count]), np.array(duts[:count]), bins, settings=settings)
        mag, ph = _hits(e.response, e.relative_type_a, e.phase_type_a_rad, e.dof, truth)
        out[f"mag{count}"], out[f"ph{count}"] = mag, ph
        out[f"u{count}"] = e.relative_type_a
    assert first_extra is not None
    ref3, dut3 = first_extra
    acc = SpectralAccumulator(n, bins, track_floor=False)
    acc.add_periods(ref3.reshape(EXTRA_PERIODS, n), dut3.reshape(EXTRA_PERIODS, n))
    periodic = acc.estimate("periodic")
    e3 = lpm.estimate(ref3, dut3, bins * EXTRA_PERIODS, settings=settings)
    out["err_periodic"] = periodic.response / truth - 1.0
    out["err_lpm3"] = e3.response / truth - 1.0
    out["err_lpm1"] = lpm.estimate(refs[0], duts[0], bins, settings=settings).response / truth - 1
    out["u_periodic"] = periodic.relative_type_a
    out["u_lpm3"] = e3.relative_type_a
    return out


def run(dut: str, trials: int, workers: int) -> list[str]:
    """The markdown rows for one DUT."""
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=workers) as pool:
        results = list(pool.map(trial, [(dut, s, SETTINGS) for s in range(trials)], chunksize=4))
    elapsed = time.perf_counter() - t0
    freqs = results[0]["freqs"]
    rows = [
        f"{dut}: {trials} trials x {REALISATIONS} realisations in {elapsed:.0f} s "
        f"(order {SETTINGS.order}, {SETTINGS.bins} bins, q = {SETTINGS.dof})",
        "",
        "| line | P = 1 magnitude / phase | P = 2 | P = 3 | u(P = 1) | var periodic / var LPM |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    cover = {}
    for count in (1, 2, 3):
        cover[count] = (
            np.mean([r[f"mag{count}"] for r in results], axis=0),
            np.mean([r[f"ph{count}"] for r in results], axis=0),
        )
    err_p = np.array([r["err_periodic"] for r in results])
    err_l = np.array([r["err_lpm3"] for r in results])
    efficiency = np.mean(np.abs(err_p) ** 2, axis=0) / np.mean(np.abs(err_l) ** 2, axis=0)
    u1 = np.median([r["u1"] for r in results], axis=0)
    for k, f in enumerate(freqs):
        cells = " | ".join(
            f"{100 * cover[c][0][k]:.1f} / {100 * cover[c][1][k]:.1f}" for c in (1, 2, 3)
        )
        rows.append(f"| {f:g} Hz | {cells} | {100 * u1[k]:.4f} % | {efficiency[k]:.2f} |")
    summary = " | ".join(
        f"{100 * min(cover[c][0].min(), cover[c][1].min()):.1f}-"
        f"{100 * max(cover[c][0].max(), cover[c][1].max()):.1f}"
        for c in (1, 2, 3)
    )
    rows.append(f"| all lines (min-max) | {summary} | | median {np.median(efficiency):.2f} |")
    ratio_u = np.median([r["u_periodic"] / r["u_lpm3"] for r in results])
    rows.append("")
    one = np.array([r["err_lpm1"] for r in results])
    rms_one = 100 * np.sqrt(np.mean(np.abs(one) ** 2, axis=0))
    rows.append(
        f"stated u, periodic (3 periods) / LPM (same 3 periods): median {ratio_u:.2f}; "
        f"observed rms error of the LPM from one period: {rms_one.min():.4f}-"
        f"{rms_one.max():.4f} % over the lines"
    )
    return rows


LOW_LEVEL_MS2 = 1.5  # the README's 0.4-8 Hz run: --level 1.5 --profile displacement --corner 3
LOW_CORNER_HZ = 3.0


def low_grid() -> lpm.LpmGrid:
    """The 0.4-8 Hz grid of `accelcal run` (app.procedure.planning.choose_period)."""
    nominal = iso266.nominal_frequencies(0.4, 8)
    return lpm.design_grid(
        nominal,
        200.0,
        tolerance=GRID_TOLERANCE,
        max_period_s=LONGEST_PERIOD_S,
        within_hz=(min(nominal), max(nominal)),
    )


def low_frequency_trial(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One 0.4-8 Hz run on the long-stroke exciter: magnitude and phase hits, u per line."""
    grid = low_grid()
    fs = grid.sample_rate_hz
    bins, n = np.array(grid.bins), grid.period_samples
    f = np.array(grid.frequencies_hz)
    profile = AmplitudeProfile(LOW_LEVEL_MS2, Profile.DISPLACEMENT, corner_hz=LOW_CORNER_HZ)
    amplitudes = profile.amplitudes(f)
    model = StandModel(exciter=EXCITER_CATALOGUE["long-stroke"], adc=AdcModel(hum_v=()))
    stand = SimulatedStand("piezo", model=model, seed=seed, systematic=False)
    fade = round(2.5 * fs)  # one cycle of 0.4 Hz
    stand.configure(
        DaqConfig(
            fs,
            fade,
            OutputChannel("sim/ao0", 10.0),
            (InputChannel("reference", "sim/ai0", 1.0), InputChannel("dut", "sim/ai1", 1.0)),
        )
    )
    response = stand.table_response(f)
    phases = np.random.default_rng([seed, 4]).uniform(0, 2 * np.pi, bins.size)
    drive = synthesize(bins, amplitudes / np.abs(response), phases - np.angle(response), n)
    played = np.concatenate([drive[:fade] * fade_envelope(fade, 1, "in"), np.roll(drive, -fade)])
    played = np.concatenate([played, np.zeros(-played.size % fade)]).reshape(-1, fade)
    stand.start(played[0])
    out = []
    for i in range(played.shape[0]):
        out.append(stand.read_period())
        if i + 1 < played.shape[0]:
            stand.write_period(played[i + 1])
    stand.stop()
    data = np.hstack(out)[:, fade : fade + n]
    e = lpm.estimate(data[0], data[1], bins)
    chain = stand._chain  # the exact sampled model: the truth, never shown to the estimator
    truth = chain.discrete_response("dut", f, fs) / (
        chain.discrete_response("reference", f, fs) * model.reference_gain
    )
    mag, ph = _hits(e.response, e.relative_type_a, e.phase_type_a_rad, e.dof, truth)
    return mag, ph, e.relative_type_a


def low_frequency(trials: int) -> list[str]:
    """The markdown rows of the 0.4-8 Hz check."""
    grid = low_grid()
    t0 = time.perf_counter()
    results = [low_frequency_trial(seed) for seed in range(trials)]
    elapsed = time.perf_counter() - t0
    mag = np.mean([r[0] for r in results], axis=0)
    ph = np.mean([r[1] for r in results], axis=0)
    u = np.median([r[2] for r in results], axis=0)
    rows = [
        f"0.4-8 Hz, long-stroke exciter, piezo, {trials} trials in {elapsed:.0f} s, period "
        f"{grid.period_s:g} s, {LOW_LEVEL_MS2:g} m/s^2, constant displacement below "
        f"{LOW_CORNER_HZ:g} Hz:",
        "",
        "| line | actual | magnitude / phase coverage | median u |",
        "| --- | --- | --- | --- |",
    ]
    for k, (f0, f) in enumerate(zip(grid.nominal_frequencies_hz, grid.frequencies_hz, strict=True)):
        rows.append(
            f"| {f0:g} Hz | {f:.4g} Hz | {100 * mag[k]:.1f} / {100 * ph[k]:.1f} | "
            f"{100 * u[k]:.3f} % |"
        )
    return rows


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    global SETTINGS
    options = dict(a.split("=", 1) for a in sys.argv[1:] if "=" in a)
    args = [a for a in sys.argv[1:] if "=" not in a]
    args = ["smoke" if a == "--smoke" else a for a in args]
    SETTINGS = lpm.LpmSettings(
        order=int(options.get("order", SETTINGS.order)),
        bins=int(options.get("bins", SETTINGS.bins)),
    )
    if args and args[0] == "low":
        for row in low_frequency(int(args[1]) if len(args) > 1 else 1000):
            log.info(row)
        return
    if args and args[0] == "smoke":
        trials, duts, workers = 4, ["piezo"], 1
    else:
        trials = int(args[0]) if args else 400
        duts = args[1:] or ["piezo", "capacitive"]
        workers = 2
    for dut in duts:
        for row in run(dut, trials, workers):
            log.info(row)


if __name__ == "__main__":
    main()
