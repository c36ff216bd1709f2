"""Real hardware, opt-in: `pytest tests/hardware --daq-device Dev1` (ao0 looped to ai0 and ai1)."""

from __future__ import annotations

import numpy as np
import pytest

from dsp.crestfactor import schroeder_phases, synthesize
from dsp.spectral import period_spectrum
from hardware.interfaces import DaqConfig, InputChannel, OutputChannel
from hardware.nidaq import NiDaq, read_teds_channels


def test_a_short_multisine_comes_back_on_both_channels_at_the_right_rate(daq_device):
    fs, n = 10_000.0, 10_000
    bins = np.array([20, 50, 130, 320])
    period = synthesize(bins, np.full(4, 0.2), schroeder_phases(np.ones(4)), n)
    config = DaqConfig(
        fs,
        n,
        OutputChannel(f"{daq_device}/ao0", 5.0),
        (
            InputChannel("reference", f"{daq_device}/ai0", 5.0),
            InputChannel("dut", f"{daq_device}/ai1", 5.0),
        ),
    )
    daq = NiDaq(daq_device)
    try:
        status = daq.configure(config)
        assert status.actual_sample_rate_hz == fs
        daq.start(period)
        daq.read_period(5.0)  # settling
        block = daq.read_period(5.0)
    finally:
        daq.stop()
    assert block.shape == (2, n)
    spectra = np.abs(period_spectrum(block))[:, bins]
    np.testing.assert_allclose(spectra, 0.2, rtol=0.05)  # every line, at its bin: right rate
    assert daq.output_v in (0.0, None)


def test_several_dut_channels_come_back_in_config_order_with_their_skews(daq_device):
    """Issue 36: the same wiring read as a reference and two DUT channels named by position, in
    one task; ai2 is not looped, so only ai0's and ai1's lines are checked."""
    fs, n = 10_000.0, 10_000
    bins = np.array([20, 50, 130, 320])
    period = synthesize(bins, np.full(4, 0.2), schroeder_phases(np.ones(4)), n)
    inputs = (
        InputChannel("reference", f"{daq_device}/ai0", 5.0),
        InputChannel("dut.A", f"{daq_device}/ai1", 5.0),
        InputChannel("dut.B", f"{daq_device}/ai2", 5.0),
    )
    config = DaqConfig(fs, n, OutputChannel(f"{daq_device}/ao0", 5.0), inputs)
    daq = NiDaq(daq_device)
    try:
        status = daq.configure(config)
        daq.start(period)
        daq.read_period(5.0)  # settling
        block = daq.read_period(5.0)
    finally:
        daq.stop()
    assert block.shape == (3, n)
    assert list(status.skews_s) == ["reference", "dut.A", "dut.B"]
    assert status.skews_s["reference"] == 0.0 and status.skew_s == status.skews_s["dut.A"]
    assert status.skews_s["dut.B"] == pytest.approx(2 * status.skews_s["dut.A"])
    spectra = np.abs(period_spectrum(block[:2]))[:, bins]
    np.testing.assert_allclose(spectra, 0.2, rtol=0.05)
    teds = read_teds_channels(inputs)
    assert list(teds) == ["reference", "dut.A", "dut.B"]
    assert all((t.data is None) != (t.reason == "") for t in teds.values())
