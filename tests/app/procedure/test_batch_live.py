"""Each other DUT of a several-DUT run estimated live (issue 36 point 4; app.procedure.batch_live):
with `Procedure.batch_live` (the GUI's Run tab asks for it) every live estimate of the run's own
DUT carries the other DUTs' after the same period, each from its own channel, and the last of
each is its stored results; a member whose estimate cannot be made is left out, the run goes on."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from app.procedure.batch import MemberChoice, open_batch
from app.procedure.events import PeriodEstimate
from app.procedure.request import RunRequest
from app.stand import config as stand_config

pytestmark = pytest.mark.integration

ROOT = Path(__file__).parents[3]
PHYSICS = ROOT / "sim" / "stand-fixture4-physics.toml"  # the positions move differently
CHOICES = [MemberChoice(p, f"SN-{p}") for p in "ABCD"]


def _batch(base: Path, estimator: str, periods: int, patch: pytest.MonkeyPatch):
    """A batch of A-D on the physics fixture with the members' live estimates, as the window
    runs it (open, the run, the stand closed, the end); (BatchFinished, events)."""
    patch.setenv("XDG_DATA_HOME", str(base / "data"))
    request = RunRequest(
        stand_file=PHYSICS,
        out=base / "runs",
        seed=7,
        periods=periods,
        estimator=estimator,
        stored_response=False,
    )
    events: list[object] = []
    opened = open_batch(request, CHOICES, events.append, config=stand_config.load(PHYSICS))
    opened.procedure.listener = events.append  # as the window's worker: unmarked
    opened.procedure.batch_live = True
    try:
        finished = opened.procedure.run()
    finally:
        opened.stand.close()
    return opened.end(finished, events.append), events


@pytest.fixture(scope="module", params=["lpm", "periodic"])
def live_batch(request, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple]:
    base = tmp_path_factory.mktemp(f"live-{request.param}")
    with pytest.MonkeyPatch.context() as patch:
        yield _batch(base, request.param, 4, patch)


def _deviations(results) -> list[float]:
    return [ln.deviation_percent for ln in results.lines]


def test_each_live_estimate_carries_the_other_duts_and_ends_at_their_stored_results(live_batch):
    finished, events = live_batch
    assert [str(one.status) for _, one in finished.members] == ["complete"] * 4
    live = [e for e in events if isinstance(e, PeriodEstimate) and not e.member]
    assert len(live) >= 2  # after each period from the estimator's least on
    for event in live:
        assert [m.position for m in event.members] == ["B", "C", "D"]
        assert [m.channel for m in event.members] == ["dut.B", "dut.C", "dut.D"]
    last = {m.position: m.results for m in live[-1].members}
    stored = {choice.position: one.results for choice, one in finished.members}
    for position in "BCD":
        assert _deviations(last[position]) == pytest.approx(
            _deviations(stored[position]), rel=1e-9, abs=1e-12
        ), position
    # each its own DUT's: the positions' DUTs differ from the run's own and from one another
    lead = _deviations(live[-1].results)
    for position in "BCD":
        assert _deviations(last[position]) != pytest.approx(lead, rel=1e-6, abs=1e-6), position
    assert _deviations(last["B"]) != pytest.approx(_deviations(last["C"]), rel=1e-6, abs=1e-6)
    # the members' own end-of-run estimates carry no others
    assert all(not e.members for e in events if isinstance(e, PeriodEstimate) and e.member)


def test_a_member_whose_live_estimate_fails_is_left_out_and_the_run_goes_on(
    tmp_path, monkeypatch, caplog
):
    from app.procedure import batch_live
    from dsp.calibration import AnalysisError

    real = batch_live.compute_results

    def failing(estimate, plan, chain, budget, **kwargs):
        if failing.member == "dut.C":
            raise AnalysisError("dead DUT channel (test)")
        return real(estimate, plan, chain, budget, **kwargs)

    failing.member = ""
    estimate = batch_live.LiveMembers._estimate

    def marked(self, channel):
        failing.member = channel
        return estimate(self, channel)

    monkeypatch.setattr(batch_live, "compute_results", failing)
    monkeypatch.setattr(batch_live.LiveMembers, "_estimate", marked)
    finished, events = _batch(tmp_path, "periodic", 4, monkeypatch)
    assert [str(one.status) for _, one in finished.members] == ["complete"] * 4
    live = [e for e in events if isinstance(e, PeriodEstimate) and not e.member]
    assert live and all([m.position for m in e.members] == ["B", "D"] for e in live)
    assert caplog.text.count("live estimate of dut.C not made") == 1  # said once
