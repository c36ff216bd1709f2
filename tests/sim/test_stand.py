"""The simulated stand behind the Daq interface: hum, determinism, faults, 0 V at the end."""

from __future__ import annotations

import numpy as np
import pytest

from hardware.errors import (
    AmplifierFaultError,
    DaqTimeoutError,
    DeviceLostError,
    OverloadError,
    VisaTimeoutError,
)
from hardware.interfaces import Daq, DaqConfig, InputChannel, OutputChannel
from sim.models import DrivenHum, StandModel
from sim.stand import Fault, SimBudget, SimulatedStand

FS, N = 6000.0, 12000
CONFIG = DaqConfig(
    FS,
    N,
    OutputChannel("sim/ao0", 10.0),
    (
        InputChannel("reference", "sim/ai0", 1.0),
        InputChannel("dut", "sim/ai1", 1.0),
        InputChannel("drive", "sim/ai2", 10.0),
    ),
)


def stand(**kwargs) -> SimulatedStand:
    s = SimulatedStand(kwargs.pop("dut", "piezo"), **kwargs)
    s.configure(CONFIG)
    return s


def drive_period(seed: int = 0) -> np.ndarray:
    i = np.arange(N)
    return 0.05 * np.sin(2 * np.pi * 320 * i / N) + 0.3 * np.sin(2 * np.pi * 40 * i / N)


def test_it_is_a_daq():
    assert isinstance(stand(), Daq)


def test_hum_at_mains_frequency_and_harmonics_with_drive_at_zero():
    s = stand()
    s.start(np.zeros(N))
    s.read_period()
    blocks = np.array([s.read_period() for _ in range(8)])
    spectrum = np.abs(np.fft.rfft(blocks[:, 0]).mean(axis=0)) * 2 / N  # periodic average
    mains_bins = [100 * h for h in range(1, 6)]  # 50 Hz harmonics on a 0.5 Hz grid
    expected = np.array(s.model.adc.hum_v)
    np.testing.assert_allclose(spectrum[mains_bins], expected, rtol=0.05, atol=1e-6)
    others = np.delete(spectrum[1:2000], np.array(mains_bins) - 1)
    assert np.max(others) < expected[-1] / 2
    assert np.all(blocks[:, 2] == 0.0)  # the drive loopback reads 0 V


def test_hum_while_driven_is_there_only_while_the_drive_is_not_at_0_v():
    """Issue 32: a power-amplifier ground loop (`DrivenHum`) adds its tone to the DUT channel
    only while driven: the drive-off background never sees it."""
    model = StandModel(driven_hum=(DrivenHum(50.3, 2e-3),))
    quiet, hummed = stand(model=model), stand()

    def dut_at_50_3(s: SimulatedStand, drive: np.ndarray) -> complex:
        s.start(drive)
        s.read_period()
        block = s.read_period()[1]
        x = np.arange(N) / FS
        return complex(2 * np.mean(block * np.exp(-2j * np.pi * 50.3 * x)))

    assert abs(dut_at_50_3(quiet, np.zeros(N))) < 1e-4  # drive off: the ADC's hum only
    drive = 0.1 * drive_period()  # the DUT channel well inside its +-1 V range
    driven = dut_at_50_3(stand(model=model), drive)
    plain = dut_at_50_3(hummed, drive)  # the same seed without the ground loop
    assert 1.9e-3 < abs(driven - plain) < 2.1e-3  # the tone's 2 mV, on top of the rest
    with pytest.raises(ValueError, match="--sim-hum '2mV'"):
        DrivenHum.parse("2mV")
    assert DrivenHum.parse("1mV/0.2mV@100Hz") == DrivenHum(100.0, 1e-3, 2e-4)
    assert DrivenHum.parse("500uV@50.3Hz") == DrivenHum(50.3, 5e-4)


def test_same_seed_gives_bit_identical_output_and_other_seeds_differ():
    runs = []
    for seed in (5, 5, 6):
        s = stand(seed=seed)
        s.start(drive_period())
        runs.append(np.hstack([s.read_period() for _ in range(3)]))
    assert np.array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0], runs[2])


def test_systematic_deviations_are_drawn_from_the_budget():
    budget = SimBudget.load()
    draws = [SimulatedStand("piezo", seed=k).deviations for k in range(400)]
    gains = np.array([d.reference_gain for d in draws]) - 1
    half_width = next(
        c.value for c in budget.budget.components if c.name == "conditioning amplifier gain"
    )
    assert np.all(np.abs(gains) <= half_width)
    assert np.std(gains) == pytest.approx(half_width / np.sqrt(3), rel=0.15)
    assert SimulatedStand("piezo", seed=1, systematic=False).deviations.reference_gain == 1.0


def test_budget_mapping_errors_name_the_field():
    with pytest.raises(ValueError, match="names no component 'nope'"):
        SimBudget.load('[simulation]\nnope = "dut_motion"\n')
    text = '[[component]]\nname = "a"\nvalue = 0.01\n[simulation]\na = "warp"\n'
    with pytest.raises(ValueError, match="'a': unknown target 'warp'"):
        SimBudget.load(text)


@pytest.mark.parametrize(
    ("kind", "error"),
    [
        ("daq-timeout", DaqTimeoutError),
        ("device-lost", DeviceLostError),
        ("amplifier-fault", AmplifierFaultError),
        ("overload", OverloadError),
    ],
)
def test_each_daq_fault_raises_at_its_time_and_stop_leaves_0_v(kind, error):
    s = stand(faults=(Fault(kind, 5.0),))
    s.start(drive_period())
    s.read_period()
    s.read_period()  # 0-4 s: fine
    with pytest.raises(error):
        s.read_period()  # the period 4-6 s holds the fault
    assert s.sim_time_s == pytest.approx(4.0)
    s.stop()
    assert s.output_v == 0.0 and s.output.final_v == 0.0 and s.output.stopped
    s.stop()  # twice is fine


def test_visa_timeout_surfaces_through_the_measuring_amplifier():
    s = stand(faults=(Fault("visa-timeout", 3.0),))
    amplifier = s.measuring_amplifier()
    assert amplifier.configure(1, sensitivity_mv_per_ms2=1.0, gain=10).gain == 10
    s.start(drive_period())
    s.read_period()
    amplifier.overloaded(1)  # at 2 s: still answering
    s.read_period()
    with pytest.raises(VisaTimeoutError):
        amplifier.read_settings(1)
    s.stop()
    assert s.output_v == 0.0


def test_over_travel_trips_the_amplifier_interlock():
    s = stand()
    i = np.arange(N)
    s.start(9.0 * np.sin(2 * np.pi * 2 * i / N))  # 1 Hz at full drive: far over 4 mm
    with pytest.raises(AmplifierFaultError, match="over-travel"):
        s.read_period()
    s.stop()
    assert s.output_v == 0.0


def test_output_is_checked_and_recorded():
    s = stand()
    with pytest.raises(ValueError, match="AO range"):
        s.start(np.full(N, 11.0))
    with pytest.raises(ValueError, match="12000 samples"):
        s.start(np.zeros(10))
    s.start(drive_period())
    s.read_period()
    played = s.output.periods[0]
    assert played.start_s == 0.0
    assert played.peak_v == pytest.approx(np.max(np.abs(drive_period())))
    assert played.first_v == drive_period()[0] and played.last_v == drive_period()[-1]
    assert s.output_v == pytest.approx(drive_period()[-1])
    s.stop()
    assert s.output_v == 0.0


def test_fault_parsing():
    assert Fault.parse("device-lost@3.5") == Fault("device-lost", 3.5)
    with pytest.raises(ValueError, match="unknown kind"):
        Fault.parse("meteor@1")
    with pytest.raises(ValueError, match="KIND@SECONDS"):
        Fault.parse("device-lost@soon")


def test_paced_stand_follows_the_wall_clock_and_unpaced_does_not(monkeypatch):
    import time

    import sim.stand

    waits: list[float] = []
    real_sleep = time.sleep

    def recorded_sleep(seconds: float) -> None:
        waits.append(seconds)
        real_sleep(seconds)

    monkeypatch.setattr(sim.stand.time, "sleep", recorded_sleep)

    config = DaqConfig(
        1000.0,
        50,  # 50 ms periods
        OutputChannel("sim/ao0", 10.0),
        (InputChannel("reference", "sim/ai0", 1.0), InputChannel("dut", "sim/ai1", 1.0)),
    )
    for paced in (True, False):
        s = SimulatedStand("piezo", paced=paced)
        s.configure(config)
        s.start(np.zeros(50))
        t0 = time.monotonic()
        for _ in range(6):
            s.read_period()
        elapsed = time.monotonic() - t0
        if paced:
            assert elapsed >= 0.29  # six 50 ms periods
        else:
            assert waits == []  # never waits for the clock (no wall-time bound assumed)
        waits.clear()
        s.stop()


@pytest.mark.parametrize(
    ("kind", "fault", "interlock"),
    [
        ("over-current", "Over-current (fault code 3)", True),
        ("amplifier-fault", "Over-temperature (fault code 2)", True),
        ("interlock", None, False),
    ],
)
def test_power_amplifier_faults_go_through_the_instrument_not_the_daq(kind, fault, interlock):
    s = stand(faults=(Fault(kind, 5.0),))
    pa = s.power_amplifier()
    assert s.power_output_on is False
    s.start(drive_period())
    silent = s.read_period()  # output off: the exciter does not move
    pa.set_output_enabled(True)
    moving = s.read_period()
    assert np.std(moving[0]) > 10 * np.std(silent[0])
    assert pa.fault() is None and pa.interlock_closed()
    s.read_period()  # 4-6 s holds the fault: the DAQ read does not raise ...
    assert pa.fault() == fault and pa.interlock_closed() is interlock  # ... the amplifier says
    tripped = s.read_period()
    assert np.std(tripped[0]) < np.std(moving[0]) / 10  # it protects itself: no more output
    pa.set_output_enabled(False)
    assert s.power_output_on is False
    s.stop()
    pa.close()


def test_a_lost_power_amplifier_session_is_device_lost():
    s = stand(faults=(Fault("amplifier-lost", 3.0),))
    pa = s.power_amplifier()
    s.start(drive_period())
    pa.set_output_enabled(True)
    s.read_period()
    assert pa.interlock_closed()
    s.read_period()  # 2-4 s: the session is lost
    with pytest.raises(DeviceLostError, match="connection lost"):
        pa.fault()
    s.stop()
    pa.close()


def test_over_travel_opens_the_power_amplifiers_interlock():
    s = stand()
    pa = s.power_amplifier()
    i = np.arange(N)
    s.start(9.0 * np.sin(2 * np.pi * 2 * i / N))  # 1 Hz at full drive: far over 4 mm
    pa.set_output_enabled(True)
    s.read_period()  # no exception from the DAQ: the interlock opens
    assert pa.interlock_closed() is False
    s.stop()
    pa.close()
