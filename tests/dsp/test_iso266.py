import pytest

from dsp import iso266


def test_preferred_values_and_exact_frequencies():
    values = iso266.nominal_frequencies(10, 4000)
    assert values[:8] == (10.0, 12.5, 16.0, 20.0, 25.0, 31.5, 40.0, 50.0)
    assert values[-3:] == (2500.0, 3150.0, 4000.0)
    assert len(iso266.nominal_frequencies(10, 2500)) == 25
    assert len(iso266.nominal_frequencies()) == 44  # 1 Hz .. 20 kHz
    assert iso266.exact_frequency(iso266.band_number(1000.0)) == pytest.approx(1000.0)
    assert iso266.exact_frequency(iso266.band_number(31.5)) == pytest.approx(31.6228, rel=1e-5)
    assert iso266.nominal_frequency(43) == 20000.0


@pytest.mark.parametrize("bad", [11.0, 0.0, -10.0, 30000.0, 50000.0, float("nan")])
def test_non_preferred_values_are_refused(bad):
    with pytest.raises(ValueError, match="ISO 266"):
        iso266.band_number(bad)
    assert not iso266.is_preferred(bad)


def test_the_table_starts_at_0_4_hz_as_iso_16063_21_does():
    """Band -4 is 10^-0.4 = 0.398 Hz, nominal 0.4; then 0.5, 0.63, 0.8, 1 Hz (R10 series)."""
    below_one = iso266.nominal_frequencies(0.4, 1.0)
    assert below_one == (0.4, 0.5, 0.63, 0.8, 1.0)
    low = iso266.nominal_frequencies(0.4, 8)
    assert low[:5] == (0.4, 0.5, 0.63, 0.8, 1.0) and low[-1] == 8.0 and len(low) == 14
    assert iso266.band_number(0.4) == -4
    assert iso266.band_number(0.63) == -2
    assert iso266.exact_frequency(-4) == pytest.approx(0.398107, rel=1e-5)
    assert iso266.nominal_frequencies(0.1, 0.45) == (0.4,)
    assert len(iso266.nominal_frequencies()) == 44  # the default still starts at 1 Hz
    assert iso266.is_preferred(0.5) and not iso266.is_preferred(0.315)
    with pytest.raises(ValueError, match=r"band number must be -4\.\.46"):
        iso266.nominal_frequency(-5)
    with pytest.raises(ValueError, match=r"0\.4 Hz-40 kHz"):
        iso266.band_number(0.6)


def test_the_series_goes_on_above_20_khz_so_a_fill_reaches_25_khz():
    """SPEC.md s.3: 25, 31.5 and 40 kHz follow 20 kHz; a resonance plan "1000,...,31500" brackets
    a 25 kHz resonance (it stopped at 20 kHz without saying so)."""
    from app.lines import parse_frequencies

    assert iso266.nominal_frequencies(16000, 40000) == (16000.0, 20000.0, 25000.0, 31500.0, 40000.0)
    assert iso266.band_number(25000.0) == 44 and iso266.band_number(31500.0) == 45
    assert iso266.exact_frequency(46) == pytest.approx(39810.7, rel=1e-5)
    assert parse_frequencies("1000,...,31500")[-3:] == [20000.0, 25000.0, 31500.0]
