"""Each DUT channel's own sampling delay in a run of several DUTs (issue 36, channels point 1):
on a multiplexed DAQ the n-th DUT channel is sampled n x 4 us after the reference, and each
member's phase is corrected with its own channel's delay (the driver's, checked against the
stand file's statement per position), never the first DUT's."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from app.io.hdf5 import read_recording
from app.procedure.analysis import analyze
from app.procedure.batch import MemberChoice, execute_batch
from app.procedure.batch_files import channel_skew_s
from app.procedure.batch_skew import SkewSource, member_skews
from app.procedure.errors import PreflightError
from app.procedure.request import RunRequest
from app.stand import config as stand_config
from app.stand.fixture import FixturePosition
from hardware.interfaces import DaqConfig, InputChannel, OutputChannel
from sim.fixture_stand import FixtureStand, channel_delays

STAND = Path(__file__).parents[3] / "sim" / "stand-fixture4.toml"
CHOICES = [MemberChoice(p, f"SN-{p}", "piezo") for p in "ABCD"]
INTERVAL_S = 4e-6  # sim/stand-fixture4.toml's [daq] skew_s: the converter's channel interval


def _stand_file(tmp_path: Path, stated: dict[str, float]) -> Path:
    """sim/stand-fixture4.toml with `skew_s` stated for the positions named in `stated`."""
    text = STAND.read_text(encoding="utf-8")
    for name, skew in stated.items():
        line = f'name = "{name}"\n'
        assert line in text
        text = text.replace(line, f"{line}skew_s = {skew!r}\n", 1)
    path = tmp_path / "stand-fixture4-skews.toml"
    path.write_text(text, encoding="utf-8")
    return path


# --- the rule, alone --------------------------------------------------------------------------


def _positions(**stated: float) -> list[FixturePosition]:
    return [FixturePosition(p, physical=f"sim/ai{i}", skew_s=stated.get(p)) for i, p in
            enumerate("ABCD", start=1)]  # fmt: skip


def test_the_drivers_delay_is_each_members_own() -> None:
    reported = {"reference": 0.0, "dut.A": 4e-6, "dut.B": 8e-6, "dut.C": 12e-6, "dut.D": 16e-6}
    skews = member_skews(_positions(), reported, 4e-6, 1e-7)
    assert {c: s.skew_s for c, s in skews.items()} == {
        "dut.A": 4e-6, "dut.B": 8e-6, "dut.C": 12e-6, "dut.D": 16e-6,
    }  # fmt: skip
    assert {s.source for s in skews.values()} == {SkewSource.DRIVER}
    assert skews["dut.D"].line() == "skew dut.D: 16 us (reported by the DAQ driver)"


def test_a_stated_delay_that_disagrees_with_the_drivers_is_refused_naming_the_position() -> None:
    reported = {"dut.A": 4e-6, "dut.B": 8e-6, "dut.C": 12e-6, "dut.D": 16e-6}
    agreeing = member_skews(_positions(D=16.05e-6), reported, 4e-6, 1e-7)  # within 0.1 us
    assert agreeing["dut.D"].skew_s == 16e-6
    with pytest.raises(PreflightError, match=r"fixture.position 'D' skew_s: .* 4 us.* 16 us"):
        member_skews(_positions(D=4e-6), reported, 4e-6, 1e-7)
    with pytest.raises(PreflightError, match="'B'"):  # no tolerance stated: they must agree
        member_skews(_positions(B=8.2e-6), reported, 4e-6, 0.0)


def test_without_the_drivers_delay_the_stated_one_holds() -> None:
    skews = member_skews(_positions(B=8e-6), {}, 4e-6, 1e-7)
    assert (skews["dut.B"].skew_s, skews["dut.B"].source) == (8e-6, SkewSource.POSITION)
    assert (skews["dut.C"].skew_s, skews["dut.C"].source) == (4e-6, SkewSource.STAND)


def test_the_simulated_multiplexer_samples_each_channel_after_the_last() -> None:
    inputs = tuple(
        InputChannel(name, f"sim/ai{i}", 5.0)
        for i, name in enumerate(["reference", "dut.A", "dut.B", "dut.C", "dut.D", "drive"])
    )
    config = DaqConfig(51200.0, 5120, OutputChannel("sim/ao0", 10.0), inputs)
    assert channel_delays(config, INTERVAL_S) == pytest.approx(
        {"reference": 0.0, "dut.A": 4e-6, "dut.B": 8e-6, "dut.C": 12e-6, "dut.D": 16e-6}
    )
    stand = FixtureStand({f"dut.{p}": "piezo" for p in "ABCD"}, seed=1, multiplexed=True)
    status = stand.configure(config)
    assert status.skews_s["dut.D"] == pytest.approx(4 * stand.model.skew_s)
    assert status.skew_s == status.skews_s["dut.A"] == pytest.approx(stand.model.skew_s)
    simultaneous = FixtureStand({f"dut.{p}": "piezo" for p in "ABCD"}, seed=1).configure(config)
    assert simultaneous.skews_s["dut.D"] == simultaneous.skews_s["dut.A"] == stand.model.skew_s


# --- a run of four DUTs -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def batch(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[object, Path]]:
    """Four piezo DUTs at A-D (periods 4), A's and D's delays stated as the DAQ has them."""
    base = tmp_path_factory.mktemp("skews")
    stand = _stand_file(base, {"A": 4e-6, "D": 1.6e-5})
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("XDG_DATA_HOME", str(base / "data"))
        request = RunRequest(
            stand_file=stand, out=base / "runs", seed=11, periods=4, stored_response=False
        )
        finished = execute_batch(request, CHOICES, config=stand_config.load(stand))
    yield finished, base / "runs"


@pytest.mark.integration
def test_each_member_is_corrected_with_its_own_channels_delay(batch) -> None:
    finished, runs = batch
    for n, (choice, one) in enumerate(finished.members, start=1):
        assert one.status == "complete", one.abort_reason
        folder = runs / str(one.record.run_id)
        recording = read_recording(folder / "recording.h5")
        assert recording.chain.skew_s == pytest.approx(n * INTERVAL_S), choice.position
        stored = json.loads((folder / "results.json").read_text())
        assert stored["reference_chain"]["skew_s"] == pytest.approx(n * INTERVAL_S)
        log = (folder / "run.log").read_text()
        assert f"skew dut.{choice.position}: {4 * n:g} us (reported by the DAQ driver)" in log
        assert channel_skew_s(finished.folder / "recording.h5", f"dut.{choice.position}") == (
            pytest.approx(n * INTERVAL_S)
        )


@pytest.mark.integration
def test_the_right_delay_puts_d_s_phase_within_u_and_the_first_duts_outside(batch) -> None:
    finished, runs = batch
    choice, one = finished.members[3]
    assert choice.position == "D"
    recording = read_recording(runs / str(one.record.run_id) / "recording.h5")
    assert recording.truth is not None
    top = int(np.argmax(recording.plan.frequencies_hz))
    assert recording.plan.frequencies_hz[top] >= 2000.0
    truth = recording.truth.phase_deg

    def phase_error(skew_s: float) -> tuple[np.ndarray, np.ndarray]:
        chain = dataclasses.replace(recording.chain, skew_s=skew_s)
        results = analyze(dataclasses.replace(recording, chain=chain)).results
        phase = np.array([np.nan if x.phase_deg is None else x.phase_deg for x in results.lines])
        u = np.array(
            [np.nan if x.phase_expanded_uncertainty_deg is None
             else x.phase_expanded_uncertainty_deg for x in results.lines]
        )  # fmt: skip
        return np.abs((phase - truth + 180.0) % 360.0 - 180.0), u

    error, u = phase_error(16e-6)  # D's own channel: the fourth after the reference
    stated = np.isfinite(error) & np.isfinite(u)
    assert stated[top] and np.all(error[stated] <= u[stated])
    error, u = phase_error(4e-6)  # the stand file's single daq.skew_s (the first DUT's)
    assert error[top] > u[top]
    assert error[top] == pytest.approx(360 * recording.plan.frequencies_hz[top] * 12e-6, rel=0.05)


@pytest.mark.integration
def test_a_position_whose_stated_delay_disagrees_is_refused_before_the_drive(tmp_path) -> None:
    stand = _stand_file(tmp_path, {"C": 4e-6})  # the DAQ samples dut.C 12 us after
    request = RunRequest(
        stand_file=stand, out=tmp_path / "runs", seed=3, periods=3, stored_response=False
    )
    finished = execute_batch(request, CHOICES, config=stand_config.load(stand))
    for _, one in finished.members:
        assert one.status == "aborted"
        assert "fixture.position 'C' skew_s" in str(one.abort_reason)
        assert one.record.excitation_time_s == 0.0
