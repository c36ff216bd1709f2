"""Mounted-resonance search (dsp.resonance): a known mode, and the simulated loose mount."""

import numpy as np
import pytest

from dsp import lpm
from dsp.crestfactor import synthesize
from dsp.multisine import fade_envelope
from dsp.resonance import ResonanceError, find_resonance
from hardware.interfaces import DaqConfig, InputChannel, OutputChannel
from sim.stand import SimulatedStand


def _mode(f, f0=1234.0, q=8.0):
    return 10.0 / (1 - (f / f0) ** 2 + 1j * f / (f0 * q))


def test_a_known_mode_is_recovered_through_noise():
    f = np.arange(100.0, 5001.0, 50.0)
    rng = np.random.default_rng(1)
    noise = 1 + 0.005 * (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size))
    r = find_resonance(f, _mode(f) * noise)
    assert r.frequency_hz == pytest.approx(1234.0, rel=3e-3)
    assert r.q == pytest.approx(8.0, rel=0.05)
    assert r.peak_ratio == pytest.approx(8.0, rel=0.05)  # |H| at f0 is Q times the DC value
    assert r.lines_used >= 5


def test_a_peak_at_the_end_or_no_peak_is_not_a_resonance():
    f = np.arange(100.0, 1101.0, 50.0)
    with pytest.raises(ResonanceError, match="above the plan"):
        find_resonance(f, _mode(f))
    with pytest.raises(ResonanceError, match="no resonance"):
        find_resonance(f, np.full(f.size, 3.0 + 0j))
    with pytest.raises(ResonanceError, match="ascending"):
        find_resonance(f[::-1], _mode(f))


def test_the_loose_mount_of_the_simulated_stand_at_low_level():
    """Lines every 25 Hz, 300-3000 Hz, 0.5 m/s^2 each, one 1 s period after a 0.1 s fade:
    the loose mount's 1200 Hz, Q 6 resonance (sim.models catalogue)."""
    fs, n = 12000.0, 12000
    bins = np.arange(300, 3001, 25)
    stand = SimulatedStand("loose", seed=2, systematic=False)
    fade = 1200
    stand.configure(
        DaqConfig(
            fs,
            fade,
            OutputChannel("sim/ao0", 10.0),
            (InputChannel("reference", "sim/ai0", 1.0), InputChannel("dut", "sim/ai1", 1.0)),
        )
    )
    response = stand.table_response(bins * fs / n)
    phases = np.random.default_rng(2).uniform(0, 2 * np.pi, bins.size)
    drive = synthesize(bins, 0.5 / np.abs(response), phases - np.angle(response), n)
    played = np.concatenate([drive[:fade] * fade_envelope(fade, 1, "in"), np.roll(drive, -fade)])
    chunks = played.reshape(-1, fade)
    stand.start(chunks[0])
    out = []
    for i in range(chunks.shape[0]):
        out.append(stand.read_period())
        if i + 1 < chunks.shape[0]:
            stand.write_period(chunks[i + 1])
    stand.stop()
    data = np.hstack(out)[:, fade:]
    e = lpm.estimate(data[0], data[1], bins)
    r = find_resonance(bins * fs / n, e.response)
    assert r.frequency_hz == pytest.approx(1200.0, rel=0.01)
    assert r.q == pytest.approx(6.0, rel=0.1)
