"""The simulated stand's exciter catalogue (issue 26): a long-stroke exciter for ISO 16063-21
from 0.4 Hz. Expected values by hand from the models' parameters."""

import math

import numpy as np
import pytest

from dsp import iso266, lpm
from dsp.crestfactor import synthesize
from dsp.multisine import fade_envelope
from dsp.profiles import AmplitudeProfile, Profile, line_displacement_pp_m
from hardware.interfaces import DaqConfig, InputChannel, OutputChannel
from sim.models import EXCITER_CATALOGUE, ExciterModel, StandModel
from sim.stand import SimulatedStand


def test_catalogue_and_the_displacement_model_at_low_frequencies():
    assert EXCITER_CATALOGUE["small"] == ExciterModel()
    long_stroke = EXCITER_CATALOGUE["long-stroke"]
    assert long_stroke.stroke_peak_to_peak_m == 0.15
    f = np.array([0.3, 0.4, 1.0])
    w = 2 * math.pi * f
    measured = np.abs(long_stroke.displacement_stage().response(f))
    np.testing.assert_allclose(measured, 1 / w**2, rtol=1e-3)  # 1/(j w)^2 within 0.1 %
    # the small exciter's integrator (poles 0.2, 0.3 Hz) is not meant for 0.4 Hz
    small = np.abs(ExciterModel().displacement_stage().response(np.array([0.4])))
    assert small[0] < 0.75 / (2 * math.pi * 0.4) ** 2


def _run(exciter: ExciterModel, amplitudes: np.ndarray, bins, n, fs, seed=0):
    stand = SimulatedStand("piezo", model=StandModel(exciter=exciter), seed=seed, systematic=False)
    fade = round(2.5 * fs)  # one cycle of 0.4 Hz
    stand.configure(
        DaqConfig(
            fs,
            fade,
            OutputChannel("sim/ao0", 10.0),
            (InputChannel("reference", "sim/ai0", 1.0), InputChannel("dut", "sim/ai1", 1.0)),
        )
    )
    response = stand.table_response(bins * fs / n)
    phases = np.random.default_rng(seed).uniform(0, 2 * np.pi, bins.size)
    drive = synthesize(bins, amplitudes / np.abs(response), phases - np.angle(response), n)
    periodic = np.roll(drive, -fade)
    played = np.concatenate([drive[:fade] * fade_envelope(fade, 1, "in"), periodic])
    played = np.concatenate([played, np.zeros(-played.size % fade)])
    chunks = played.reshape(-1, fade)
    stand.start(chunks[0])
    out = []
    try:
        for i in range(chunks.shape[0]):
            out.append(stand.read_period())
            if i + 1 < chunks.shape[0]:
                stand.write_period(chunks[i + 1])
    finally:
        stand.stop()
    data = np.hstack(out)[:, fade : fade + n]
    return stand, data


def test_long_stroke_exciter_runs_0_4_to_8_hz_and_the_lpm_finds_the_truth():
    fs = 200.0
    grid = lpm.design_grid(iso266.nominal_frequencies(0.4, 8), fs, tolerance=0.02)
    assert grid.period_s == pytest.approx(17.65)
    bins = np.array(grid.bins)
    f = np.array(grid.frequencies_hz)
    profile = AmplitudeProfile(5.0, Profile.DISPLACEMENT, corner_hz=4.0, stroke_peak_to_peak_m=0.15)
    amplitudes = profile.amplitudes(f)  # 5 (f/4)^2 m/s^2 below 4 Hz: 15.8 mm p-p per line
    per_line = line_displacement_pp_m(f, amplitudes)
    assert per_line[0] == pytest.approx(2 * 5 / (2 * math.pi * 4) ** 2, rel=1e-9)  # 15.8 mm
    assert per_line.max() > ExciterModel().stroke_peak_to_peak_m  # beyond the small one
    stand, data = _run(EXCITER_CATALOGUE["long-stroke"], amplitudes, bins, grid.period_samples, fs)
    e = lpm.estimate(data[0], data[1], bins)
    # the truth: the stand's exact sampled model (ZOH and the DUT channel's skew included),
    # never shown to the estimator
    chain = stand._chain
    truth = chain.discrete_response("dut", f, fs) / (
        chain.discrete_response("reference", f, fs) * stand.model.reference_gain
    )
    z = np.concatenate(
        [
            (e.response / truth - 1).real / e.relative_type_a,
            (e.response / truth - 1).imag / e.phase_type_a_rad,
        ]
    )
    assert np.all(np.abs(z) <= 4.0)  # t(18) beyond 4: 0.08 %
    assert 0.5 <= np.sqrt(np.mean(z**2)) <= 1.5  # the stated u is the size of the errors
    assert np.max(e.relative_type_a) < 0.01  # the lines are well above the noise
