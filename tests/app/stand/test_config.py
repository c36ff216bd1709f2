"""Stand configuration: the shipped files load; every error names its field."""

from __future__ import annotations

from pathlib import Path

import pytest

from app.stand import config as stand_config
from app.stand.config import ConfigError, parse
from app.stand.exciters import with_exciter_budget
from app.stand.open import open_stand
from dsp.uncertainty import Quantity

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "stand-pxi6251.toml"


def test_built_in_simulated_stand_and_the_example_load():
    sim = stand_config.load()
    assert sim.backend == "sim" and sim.limits.displacement_peak_to_peak_m == 8e-3
    assert [c.name for c in sim.inputs] == ["reference", "dut", "drive"]
    real = stand_config.load(EXAMPLE)
    assert real.backend == "nidaqmx" and real.measuring_amplifier == "GPIB0::12::INSTR"
    chain = real.reference_chain()
    assert chain.reference_gain == 10.0 and chain.skew_s == 4e-6
    assert real.reference.certificate_date == "2026-03-15"
    assert len(real.budget.components) == 13  # 12 stated, the skew tolerance's phase term
    assert real.missing_components() == [] and sim.missing_components() == []


def test_real_backend_is_never_replaced_by_the_simulator():
    """This machine has no NI-DAQmx driver: the stand says so first, by name."""
    from hardware.errors import DaqNotFoundError

    with pytest.raises(DaqNotFoundError, match="NI-DAQmx is not installed"):
        open_stand(stand_config.load(EXAMPLE))


def test_a_missing_device_is_named(monkeypatch):
    from hardware import discovery
    from hardware.errors import DaqNotFoundError

    monkeypatch.setattr(discovery, "list_ni_devices", lambda: [{"name": "Dev1"}])
    with pytest.raises(
        DaqNotFoundError, match=r"daq\.device 'PXI1Slot2' not found; NI-DAQmx sees Dev1"
    ):
        open_stand(stand_config.load(EXAMPLE))


def mutate(old: str, new: str) -> str:
    text = EXAMPLE.read_text()
    assert old in text, old
    return text.replace(old, new, 1)


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ('backend = "nidaqmx"', 'backend = "labview"', "daq.backend: must be one of sim, nidaqmx"),
        ("[limits]\n", "[limitz]\n", "limits: missing section"),
        (
            "displacement_peak_to_peak_m = 8e-3",
            "displacement_peak_to_peak_m = -1",
            "limits.displacement_peak_to_peak_m: must be > 0",
        ),
        ("drive_peak_v = 5.0", "drive_peak_v = 12.0", "limits.drive_peak_v: exceeds the output"),
        (
            'physical = "PXI1Slot2/ai1"\nrange_v = 5.0',
            'physical = "PXI1Slot2/ai1"\nrange_v = "5"',
            "daq.dut.range_v: must be a number",
        ),
        (
            'terminal = "rse"',
            'terminal = "rse"\ncoupling = "magnetic"',
            "daq.drive.coupling: must be 'dc' or 'ac'",
        ),
        ("skew_s = 4e-6", "skew_s = 0.5", "daq.skew_s: must be between 0 and 1 ms"),
        ('certificate_number = "PTB-2026-0815"\n', "", "reference.certificate_number: missing"),
        (
            "frequencies_hz = [10.0, 20.0,",
            "frequencies_hz = [20.0, 10.0,",
            "reference: frequencies_hz must be positive and increasing",
        ),
        ('distribution = "rectangular"', 'distribution = "gaussian-ish"', "component:"),
        ("[dut_channel]\ngain = 1.0", "[dut_channel]\ngain = 0", "dut_channel.gain: must be > 0"),
        (
            "[laboratory]",
            '[simulation]\nx = "dut_motion"\n[laboratory]',
            "simulation: only for the simulated stand",
        ),
        (
            "reference_channel = 1",
            "reference_channel = 1.5",
            "amplifiers.reference_channel: must be an integer",
        ),
    ],
)
def test_errors_name_the_field(old, new, message):
    with pytest.raises(ConfigError) as info:
        parse(mutate(old, new), "stand.toml")
    assert str(info.value).startswith("stand.toml: ")
    assert message in str(info.value)


def test_not_toml_and_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="not valid TOML"):
        parse("[daq\n", "x.toml")
    with pytest.raises(ConfigError, match="no such file"):
        stand_config.load(tmp_path / "none.toml")


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            "skew_s = 4e-6",
            "skew_seconds = 4e-6",
            "daq.skew_seconds: unknown key; did you mean 'skew_s'?",
        ),
        ("[dut_channel]", "[dut_chanel]", "dut_chanel: unknown key; did you mean 'dut_channel'?"),
        (
            "gain = 1.0",
            "gain = 1.0\ngian = 2.0",
            "dut_channel.gian: unknown key; did you mean 'gain'?",
        ),
        ("[limits]\n", "[limits]\nstroke_mm = 8\n", "limits.stroke_mm: unknown key"),
    ],
)
def test_an_unknown_key_is_refused_naming_the_nearest_known_one(old, new, message):
    with pytest.raises(ConfigError) as info:
        parse(mutate(old, new), "stand.toml")
    assert message in str(info.value)


def test_a_certificate_table_of_known_keys_is_accepted():
    text = EXAMPLE.read_text() + '\n[certificate]\ncustomer = "ACME"\nauthorised_by = "J. S."\n'
    assert parse(text, "stand.toml").raw["certificate"]["customer"] == "ACME"


@pytest.mark.parametrize(
    ("channel", "clash"),
    [("dut", "reference"), ("drive", "reference"), ("drive", "dut")],
)
def test_one_physical_channel_for_two_inputs_is_refused(channel, clash):
    config = stand_config.load(EXAMPLE)
    physical = {c.name: c.physical for c in config.inputs}
    text = EXAMPLE.read_text()
    section = f"[daq.{channel}]"
    head, tail = text.split(section, 1)
    tail = tail.replace(f'physical = "{physical[channel]}"', f'physical = "{physical[clash]}"', 1)
    with pytest.raises(ConfigError) as info:
        parse(head + section + tail, "stand.toml")
    assert f"daq.{channel}.physical: '{physical[clash]}' is also daq.{clash}.physical" in str(
        info.value
    )


SIM_TEXT = (Path(stand_config.__file__).parents[2] / "sim" / "stand.toml").read_text()


def test_the_long_stroke_exciter_has_its_own_budget_terms():
    """Issue 32 point 5: on the long-stroke exciter its rocking mode, guidance errors and the
    reference's low-frequency term replace the stand's terms of those kinds; the small
    exciter's budget is the stand's own."""
    sim = stand_config.load()
    small = {c.name for c in with_exciter_budget(sim, "small").budget.components}
    assert small == {c.name for c in sim.budget.components}
    long = with_exciter_budget(sim, "long-stroke").budget
    names = {c.name for c in long.components}
    assert "transverse motion" not in names  # the small exciter's, growing above 2 kHz
    assert "reference frequency response (interpolation, drift) above 2 kHz" not in names
    assert "transverse motion: long-stroke rocking mode (60 Hz)" in names

    def u_b(f: float) -> float:
        return long.type_b(f, Quantity.MAGNITUDE)[0]

    assert u_b(0.4) > u_b(8.0) > 0  # the reference's term grows below 2 Hz
    assert u_b(60.0) > u_b(8.0)  # the rocking mode
    assert with_exciter_budget(sim, "long-stroke").missing_components() == []


@pytest.mark.parametrize(
    ("added", "message"),
    [
        ("[exciters.small]\nstroke = 1\n", "exciters.small: holds only"),
        ("[exciters.small]\n", "exciters.small: states no component"),
        (
            '[[exciters.small.component]]\nname = "x"\nvalue = 0.001\n'
            'kind = "transverse"\ndistribution = "rectangular"\n',
            "exciters.small.component:",
        ),
    ],
)
def test_an_exciter_section_is_checked_naming_the_field(added, message):
    text = SIM_TEXT.replace("[simulation]\n", added + "\n[simulation]\n")
    with pytest.raises(ConfigError, match=message):
        parse(text, "stand.toml")
    real = EXAMPLE.read_text() + '\n[[exciters."long-stroke".component]]\nname = "x"\n'
    with pytest.raises(ConfigError, match="exciters: only for the simulated stand"):
        parse(real, "stand.toml")
