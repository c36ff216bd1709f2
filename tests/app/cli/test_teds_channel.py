"""`accelcal teds read --channel dut.<position>` (issue 36, channels point 4): one DUT input of
the stand file's fixture; the simulated fixture gives each position's sensor its own TEDS, a
real stand reads the channel through hardware.nidaq.read_teds_channels (an injected nidaqmx
here); bad channels are refused naming --channel, exit 2."""

from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import pytest

import hardware.nidaq as nidaq
from app.cli import main
from hardware.teds import bitstream_bytes, read_ted_file
from sim.teds import position_serial
from tests.hardware.test_nidaq_channels import FakeNi

ROOT = Path(__file__).parents[3]
STAND = ROOT / "sim" / "stand-fixture4.toml"
TEDS_DATA = ROOT / "tests" / "data" / "teds"


def _serial(text: str) -> int:
    match = re.search(r"serial (\d+)", text)
    assert match is not None, text
    return int(match.group(1))


def test_each_position_of_the_simulated_fixture_has_its_own_teds(capsys) -> None:
    serials = {}
    for channel in ("dut.A", "dut.B", "dut.D"):
        argv = ["teds", "read", "--stand", str(STAND), "--channel", channel, "--seed", "4"]
        assert main(argv) == 0
        out = capsys.readouterr().out
        assert out.startswith(f"TEDS on simulated stand, {channel} DUT 'piezo':")
        assert re.search(r"sensitivity 10\.[12]\d* mV/\(m/s\^2\)", out), out
        serials[channel] = _serial(out)
    assert serials == {
        "dut.A": position_serial(4, 0), "dut.B": position_serial(4, 1),
        "dut.D": position_serial(4, 3),
    }  # fmt: skip
    assert len(set(serials.values())) == 3
    assert main(["teds", "read", "--seed", "4"]) == 0  # without --channel: as it always was
    assert _serial(capsys.readouterr().out) == position_serial(4, 0)


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["--stand", str(STAND), "--channel", "dut.Q"], "--channel 'dut.Q': not a DUT channel"),
        (["--stand", str(STAND), "--channel", "reference"], "dut.A, dut.B, dut.C, dut.D"),
        (["--channel", "dut.B"], "--channel dut.B: the stand file"),
    ],
)
def test_a_channel_the_stand_does_not_have_is_refused_naming_it(argv, named, capsys) -> None:
    assert main(["teds", "read", *argv]) == 2
    err = capsys.readouterr().err
    assert named in err and "Traceback" not in err


def _nidaq_stand(tmp_path: Path) -> Path:
    """examples/stand-pxi6251.toml with sim/stand-fixture4.toml's fixture on its inputs
    (PXI1Slot2/ai1, ai3, ai4, ai5)."""
    text = (ROOT / "examples" / "stand-pxi6251.toml").read_text(encoding="utf-8")
    fixture = STAND.read_text(encoding="utf-8").split("\n[fixture]\n", 1)[1]
    text += "\n[fixture]\n" + fixture.replace('"sim/ai', '"PXI1Slot2/ai')
    path = tmp_path / "stand-ni.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_a_real_stand_reads_the_channels_teds_on_its_physical_input(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    accelerometer = bitstream_bytes(read_ted_file(TEDS_DATA / "Accelerometer.ted"))
    ni = FakeNi({"PXI1Slot2/ai3": accelerometer, "PXI1Slot2/ai4": b""})
    monkeypatch.setattr(nidaq, "import_nidaqmx", lambda: SimpleNamespace(system=ni.system))
    stand = _nidaq_stand(tmp_path)
    assert main(["teds", "read", "--stand", str(stand), "--channel", "dut.B"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("TEDS on PXI1Slot2 dut.B PXI1Slot2/ai3:")
    assert ("configure_teds", "PXI1Slot2/ai3", None) in ni.events
    assert not any("PXI1Slot2/ai1" in e for e in ni.events)  # dut.A's input is not touched
    assert main(["teds", "read", "--stand", str(stand), "--channel", "dut.C"]) == 2
    assert "TEDS on dut.C (PXI1Slot2/ai4):" in capsys.readouterr().err  # an empty memory: said so
