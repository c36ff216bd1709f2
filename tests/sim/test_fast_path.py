"""The simulated stand's fast path (real sections, tabled hum) equals the previous algorithm
(complex modal recursions, hum computed per block) for a fixed seed."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from hardware.interfaces import DaqConfig, InputChannel, OutputChannel
from sim.lti import MultiZoh
from sim.stand import SimulatedStand


def complex_modal(zoh: MultiZoh, u: np.ndarray, state: np.ndarray) -> dict[str, np.ndarray]:
    """The previous `MultiZoh.process`: one complex first-order recursion per mode."""
    modes = np.empty((zoh._poles.size, u.size), complex)
    for i, pole in enumerate(zoh._poles):
        modes[i], zf = scipy.signal.lfilter([0.0, zoh._inputs[i]], [1.0, -pole], u, zi=[state[i]])
        state[i] = zf[0]
    y = (zoh._outputs @ modes).real + zoh._direct[:, None] * u
    return dict(zip(zoh.names, y, strict=True))


def configured(dut: str, fs: float, seed: int = 3) -> SimulatedStand:
    stand = SimulatedStand(dut, seed=seed)
    stand.configure(
        DaqConfig(
            fs,
            int(fs),
            OutputChannel("ao0", 10.0),
            (InputChannel("reference", "ai0", 1.0), InputChannel("dut", "ai1", 5.0)),
        )
    )
    return stand


@pytest.mark.parametrize(("dut", "fs"), [("piezo", 6000.0), ("capacitive", 51200.0)])
def test_real_sections_equal_the_complex_modal_recursions(dut: str, fs: float) -> None:
    stand = configured(dut, fs)
    zoh = stand._chain
    state = np.zeros(zoh._poles.size, complex)
    rng = np.random.default_rng(7)
    for size in (int(fs), 1, 333, int(fs) // 2):  # block sizes, the state carried across
        u = 20.0 * rng.standard_normal(size) + 3.0
        fast, previous = zoh.process(u), complex_modal(zoh, u, state)
        for name in zoh.names:
            scale = np.max(np.abs(previous[name]))
            assert np.max(np.abs(fast[name] - previous[name])) <= 5e-12 * scale, name


def test_tabled_hum_equals_the_hum_computed_per_block() -> None:
    stand = configured("piezo", 12000.0)
    for start, n in ((0, 12000), (12000, 12000), (5, 7), (123_457, 30000)):
        stand._sample_index = start
        tabled = stand._hum(n, 12000.0)
        direct = stand._hum_block(start, n, 12000.0)
        for a, b in zip(tabled, direct, strict=True):
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-15)


def test_the_stand_reads_what_the_previous_algorithm_read(monkeypatch: pytest.MonkeyPatch) -> None:
    """End to end, the ADC codes: equal but for a code where the two algorithms' rounding
    (1e-12 relative) falls either side of a quantisation step."""
    periods = []
    for previous in (False, True):
        stand = configured("capacitive", 12000.0)
        if previous:
            state = np.zeros(stand._chain._poles.size, complex)
            chain = stand._chain
            monkeypatch.setattr(
                chain, "process", lambda u, c=chain, z=state: complex_modal(c, u, z)
            )
            monkeypatch.setattr(
                stand, "_hum", lambda n, fs, s=stand: s._hum_block(s._sample_index, n, fs)
            )
        stand.start(0.5 * np.sin(2 * np.pi * 80.0 * np.arange(12000) / 12000.0))
        periods.append(np.hstack([stand.read_period() for _ in range(4)]))
    fast, previous = periods
    step = 2.0 * np.array([[1.0], [5.0]]) / 2**16
    assert np.all(np.abs(fast - previous) <= step * 1.000001)
    assert np.mean(fast != previous) < 1e-4
