"""Each model of the simulated stand checked against its physics (SPEC.md s.13)."""

from __future__ import annotations

import numpy as np
import pytest

from sim.lti import Model, MultiZoh, Network, ZohFilter, resonance
from sim.models import DUT_CATALOGUE, AdcModel, ExciterModel, PowerAmplifierModel


def test_zoh_filter_is_exact_for_a_held_input_and_block_size_invariant():
    fs = 1000.0
    model = Model((resonance(50.0, 2.0),), 3.0)
    flt = ZohFilter(model, fs)
    step = flt.process(np.ones(2000))
    # a held constant input: the sampled step response of the continuous model, settling to 3
    assert step[0] == 0.0 and step[-1] == pytest.approx(3.0, rel=1e-9)
    x = np.random.default_rng(0).standard_normal(5000)
    flt.reset()
    whole = flt.process(x)
    flt.reset()
    pieces = np.concatenate([flt.process(x[i : i + 337]) for i in range(0, x.size, 337)])
    np.testing.assert_allclose(pieces, whole, rtol=0, atol=1e-12)


def test_steady_sine_through_the_sampled_model_matches_its_discrete_response():
    fs, n = 6000.0, 12000
    flt = ZohFilter(ExciterModel().acceleration_model(), fs, delay_s=5e-6)
    for f in (10.0, 160.0, 2500.0):
        i = np.arange(4 * n)
        u = np.sin(2 * np.pi * f * i / fs)
        flt.reset()
        y = flt.process(u)[-n:]
        m = int(f * n / fs)
        measured = np.fft.rfft(y)[m] / np.fft.rfft(u[-n:])[m]
        expected = flt.discrete_response(np.array([f]), fs)[0]
        assert measured == pytest.approx(expected, rel=1e-9)


def test_exciter_resonances_sit_where_configured():
    exciter = ExciterModel(suspension_hz=150.0, axial_resonance_hz=16000.0)
    f = np.geomspace(20, 40000, 20000)
    magnitude = np.abs(exciter.acceleration_model().response(f))
    # voltage drive: +40 dB/decade below the suspension resonance, peak near it, flat mid band
    low = np.abs(exciter.acceleration_model().response(np.array([10.0, 20.0])))
    assert low[1] / low[0] == pytest.approx(4.0, rel=0.05)
    suspension_peak = f[np.argmax(np.where(f < 1000, magnitude, 0))]
    assert 150 <= suspension_peak <= 200  # Q 1.5 peaks a little above w0
    axial_peak = f[np.argmax(np.where(f > 5000, magnitude, 0))]
    assert axial_peak == pytest.approx(16000, rel=0.01)
    mid = np.abs(exciter.acceleration_model().response(np.array([1000.0])))[0]
    assert mid == pytest.approx(exciter.midband_ms2_per_v, rel=0.1)


def test_harmonic_distortion_grows_with_level():
    exciter = ExciterModel()
    t = np.arange(1000) / 1000
    ratios = []
    for amplitude in (2.0, 8.0, 32.0):
        v = amplitude * np.sin(2 * np.pi * 10 * t)
        spectrum = np.abs(np.fft.rfft(exciter.nonlinearity(v)))
        ratios.append((spectrum[20] ** 2 + spectrum[30] ** 2) ** 0.5 / spectrum[10])
    assert ratios[0] < ratios[1] < ratios[2]
    assert ratios[0] < 0.002 and ratios[2] > 0.01
    # amplitude-dependent gain: compression of the fundamental at high level
    v = 32.0 * np.sin(2 * np.pi * 10 * t)
    gain = np.abs(np.fft.rfft(exciter.nonlinearity(v)))[10] / np.abs(np.fft.rfft(v))[10]
    assert gain < 0.99


def test_mems_dut_is_3_db_down_at_its_cut_off_and_piezo_is_flat():
    mems = DUT_CATALOGUE["capacitive"]
    s = np.abs(mems.sensitivity(np.array([10.0, 200.0])))
    assert 20 * np.log10(s[1] / s[0]) == pytest.approx(-3.0, abs=0.1)
    piezo = np.abs(DUT_CATALOGUE["piezo"].sensitivity(np.array([10.0, 160.0, 2500.0])))
    assert np.all(np.abs(piezo / piezo[1] - 1) < 0.02)
    assert np.abs(DUT_CATALOGUE["dead"].sensitivity(np.array([160.0])))[0] == 0.0


def test_quantisation_step_is_span_over_2_to_the_16_and_clips():
    adc = AdcModel()
    x = np.linspace(-1.2, 1.2, 400_001)  # 0.2 LSB apart: every code of width >= 0.5 LSB is hit
    q = adc.quantise(x, 1.0)
    step = 2.0 / 2**16
    np.testing.assert_allclose(np.round(q / step), q / step, atol=1e-9)
    assert np.unique(np.round(np.diff(np.unique(q)) / step)).tolist() == [1.0]  # no missing code
    assert q.max() == pytest.approx(1.0 - step) and q.min() == -1.0


def test_the_simulated_converter_has_its_stated_dnl_and_offers_its_ranges():
    adc = AdcModel(dnl_lsb=0.25)
    step = 2 * 0.1 / 2**16
    x = np.arange(-200.0, 200.0, 0.01) * step  # 100 samples per LSB near zero
    codes = np.round(adc.quantise(x, 0.1) / step)
    widths = np.diff(np.flatnonzero(np.diff(codes))) * 0.01  # LSB, codes wholly inside the ramp
    assert 0.5 - 0.02 <= widths.min() < 0.8 and 1.2 < widths.max() <= 1.5 + 0.02
    ideal = np.round(AdcModel(dnl_lsb=0.0).quantise(x, 0.1) / step)
    assert np.max(np.abs(codes - ideal)) == 1  # a transition moves by less than one LSB
    assert adc.coerced_range(0.1) == 0.1 and adc.coerced_range(0.3) == 0.5
    assert adc.coerced_range(10.0) == 10.0 and adc.coerced_range(10.5) is None


def test_anti_imaging_filter_passes_045_fs_and_stops_images():
    fs = 6000.0
    flt = PowerAmplifierModel().anti_imaging(fs)
    passband = np.abs(flt.response(np.array([10.0, 2500.0, 0.45 * fs])))
    assert np.all(np.abs(20 * np.log10(passband)) < 0.11)
    assert np.abs(flt.response(np.array([0.55 * fs])))[0] < 1e-4  # 80 dB


def test_network_shares_a_front_end_between_outputs():
    fs = 2000.0
    front = Model((resonance(100.0, 1.0),), 2.0)
    branch = Model((resonance(300.0, 5.0),), 0.5)
    net = Network().add("a", front).add("b", branch, "a").combine("c", {"a": 1.0, "b": -2.0})
    sim = MultiZoh(net, {"a": ("a", 0.0), "b": ("b", 0.0), "c": ("c", 0.0)}, fs)
    f = np.array([50.0, 400.0])
    direct = ZohFilter(Model(front.stages + branch.stages, 1.0), fs).discrete_response(f, fs)
    np.testing.assert_allclose(sim.discrete_response("b", f, fs), direct, rtol=1e-9)
    out = sim.process(np.random.default_rng(1).standard_normal(500))
    np.testing.assert_allclose(out["c"], out["a"] - 2 * out["b"], atol=1e-12)


def test_a_heavier_dut_lowers_the_exciters_gain_and_suspension_as_its_mass_says():
    """Force per volt on the whole moving mass M: M = 100 g + rated 10 g = 110 g; with a 150 g
    DUT M = 250 g, so the mid band falls to 110/250 = 0.44 (100 -> 44 m/s^2/V), the suspension
    to 150 sqrt(0.44) = 99.50 Hz and its Q rises to 1.5/sqrt(0.44) = 2.261."""
    rated = ExciterModel()
    assert rated.loaded(10.0) is rated  # the rated load: the figures as given
    heavy = rated.loaded(150.0)
    assert heavy.midband_ms2_per_v == pytest.approx(44.0, rel=1e-12)
    assert heavy.suspension_hz == pytest.approx(99.4987, rel=1e-5)
    assert heavy.suspension_q == pytest.approx(2.26134, rel=1e-5)
    at_2k = np.array([2000.0])
    ratio = heavy.acceleration_model().response(at_2k) / rated.acceleration_model().response(at_2k)
    assert abs(ratio[0]) == pytest.approx(0.44, rel=0.01)  # well above both suspensions
    with pytest.raises(ValueError, match="DUT mass"):
        rated.loaded(-5.0)
