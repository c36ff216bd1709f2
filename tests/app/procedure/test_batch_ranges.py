"""Each DUT channel's own input range in a run of several DUTs (issue 36, channels point 2):
picked from its own DUT's predicted peak (its nominal sensitivity), as a single run picks its
DUT's, never the first DUT's for every channel."""

from __future__ import annotations

from pathlib import Path

import pytest

from app.io.hdf5 import read_recording
from app.procedure.batch import MemberChoice, execute_batch
from app.procedure.ranging import PREDICTED_HEADROOM, member_ranges, plan_ranges
from app.procedure.request import RunRequest
from app.procedure.run import request_plan, with_stand_plan
from app.stand import config as stand_config
from hardware.interfaces import choose_range

STAND = Path(__file__).parents[3] / "sim" / "stand-fixture4.toml"


def test_each_dut_channel_is_ranged_from_its_own_nominal() -> None:
    config = stand_config.load(STAND)
    plan = request_plan(with_stand_plan(RunRequest(stand_file=STAND), config.plan))
    ranges = plan_ranges(plan, config, None, 10.2, config.input_ranges_v, per_line=False)
    chosen = member_ranges(ranges, plan, {"dut.A": 10.2, "dut.B": 35.0, "dut.C": None}, 1.0)
    peak = plan.predicted_peaks().acceleration_ms2
    allowed = ranges.allowed_v["dut"]
    assert chosen["dut.A"] == choose_range(peak * 10.2e-3, allowed, PREDICTED_HEADROOM)
    assert chosen["dut.B"] == choose_range(peak * 35e-3, allowed, PREDICTED_HEADROOM)
    assert chosen["dut.B"] > chosen["dut.A"]  # the more sensitive DUT: a larger range
    assert chosen["dut.C"] == ranges.run_ranges["dut"]  # no nominal: the run's DUT range
    unchosen = plan_ranges(plan, config, None, 10.2, (), per_line=False)  # no offered ranges
    assert member_ranges(unchosen, plan, {"dut.B": 35.0}, 1.0) == {"dut.B": 5.0}


@pytest.mark.integration
def test_a_more_sensitive_dut_beside_the_first_gets_its_own_range(tmp_path: Path) -> None:
    request = RunRequest(
        stand_file=STAND, out=tmp_path / "runs", seed=5, periods=3, stored_response=False
    )
    choices = [MemberChoice("A", "SN-P", "piezo"), MemberChoice("B", "SN-C", "capacitive")]
    finished = execute_batch(request, choices, config=stand_config.load(STAND))
    ranges = {}
    for choice, one in finished.members:
        assert one.status == "complete", one.abort_reason
        folder = tmp_path / "runs" / str(one.record.run_id)
        recording = read_recording(folder / "recording.h5")
        ranges[choice.position] = recording.ranges_v["dut"]
        assert f"input range dut.{choice.position}: +-{ranges[choice.position]:g} V" in (
            (folder / "run.log").read_text()
        )
        assert recording.truth is not None
        stated = 0
        for line, truth in zip(
            one.results.lines, recording.truth.sensitivity_mv_per_ms2, strict=True
        ):
            if line.not_stated:  # the capacitive DUT's roll-off: too few LSB up there
                continue
            stated += 1
            assert abs(line.sensitivity_mv_per_ms2 - truth) <= line.expanded_uncertainty_mv_per_ms2
        assert stated >= len(one.results.lines) // 2
    # the capacitive DUT (35 mV/(m/s^2)) would overload the piezo's (10.2) +-2 V range
    assert ranges == {"A": 2.0, "B": 5.0}
