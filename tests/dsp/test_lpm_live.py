"""The live LPM record (issue 34): up to WHOLE_RECORD_PERIODS the whole record after every
period as before; beyond, the batched estimator `analyze` uses, at checkpoints, fed from a spool
as the periods arrive: bit-identical to `record_estimate_batches` over 16-period batches, the
work per added period bounded and O(P) in all, no period held in memory."""

from __future__ import annotations

import numpy as np
import pytest

from dsp import iso266
from dsp.crestfactor import synthesize
from dsp.lpm_live import (
    BATCH_PERIODS,
    MAX_GROWTH,
    MIN_GROWTH,
    LiveRecord,
    PeriodSpool,
    next_checkpoint,
)
from dsp.lpm_record import (
    WHOLE_RECORD_PERIODS,
    BatchedRecord,
    record_estimate,
    record_estimate_batches,
)
from dsp.multisine import make_plan

FS, N = 2000.0, 1000  # 2 Hz bins, one 0.5 s period
FREQUENCIES = iso266.nominal_frequencies(10.0, 400.0)


def _plan():
    phases = np.random.default_rng(3).uniform(0, 2 * np.pi, len(FREQUENCIES))
    return make_plan(FREQUENCIES, FS, N, 1.0, 160.0, phases_rad=phases)


def _record(plan, periods, seed=1):
    """Reference, DUT (0.5 u with a slight cubic term and a decaying transient, noise on both)
    and the drive, each (periods, N)."""
    rng = np.random.default_rng(seed)
    drive = synthesize(plan.bins, np.ones(len(plan.lines)), plan.phases_rad, N)
    u = np.tile(drive, periods)
    t = np.arange(u.size) / FS
    y = 0.5 * (u - 0.002 * u**3) + 1e-3 * np.exp(-t / 0.2) + 1e-5 * rng.standard_normal(u.size)
    u = u + 1e-5 * rng.standard_normal(u.size)
    return u.reshape(periods, N), y.reshape(periods, N), np.tile(drive, (periods, 1))


def _same(a, b) -> None:
    """Two estimates equal bit for bit in every stated array."""
    for name in (
        "response",
        "relative_type_a",
        "phase_type_a_rad",
        "dof",
        "reference_noise_v",
        "dut_noise_v",
        "dut_distortion",
    ):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def _batches(ref, dut, drive, size=BATCH_PERIODS):
    for a in range(0, ref.shape[0], size):
        yield ref[a : a + size], dut[a : a + size], drive[a : a + size]


def test_the_next_checkpoint_follows_the_pace_within_its_growth_bounds():
    # type A 2x the target: 4x the periods, but at most twice the record
    assert next_checkpoint(16, 0.002, 0.001) == 32
    assert next_checkpoint(40, 0.0011, 0.001) == 49  # 48.4 -> 49 (within 40 .. 80)
    assert next_checkpoint(40, 0.00101, 0.001) == 40 + 5  # at least 1/8 more: bounded work
    assert next_checkpoint(40, 0.0009, 0.001) == 45  # below the target (a new estimate) too
    assert next_checkpoint(16, 0.01, 0.001, last=25) == 25  # never past the last period
    assert next_checkpoint(24, 0.01, None) == 48  # no target: the longest step
    assert next_checkpoint(24, float("nan"), 0.001) == 48
    assert next_checkpoint(3, 0.002, 0.001, last=3) == 4  # always ahead of the record
    assert (MIN_GROWTH, MAX_GROWTH) == (0.125, 1.0)


def test_the_spool_gives_back_the_periods_it_was_given():
    rng = np.random.default_rng(0)
    periods = [rng.standard_normal((3, 50)) for _ in range(5)]
    spool = PeriodSpool(50, 3)
    try:
        for block in periods:
            spool.append(*block)
        a, b, c = spool.read(1, 4)
        for i, channel in enumerate((a, b, c)):
            assert channel.flags.c_contiguous and channel.shape == (3, 50)
            np.testing.assert_array_equal(channel, np.array([p[i] for p in periods[1:4]]))
        with pytest.raises(ValueError, match=r"periods 3\.\.5 of 5"):
            spool.read(3, 6)
        with pytest.raises(ValueError, match="3 channels of 50 samples"):
            spool.append(np.zeros(50), np.zeros(50))
    finally:
        spool.close()


def test_a_live_record_states_what_the_whole_and_the_batched_estimators_state():
    """The live record's estimates equal, bit for bit, the whole record's up to 16 periods and
    analyze's batched one (16-period batches) beyond; the work per added period is at most
    two batches; no period is held in memory past 16."""
    plan = _plan()
    periods = 40
    ref, dut, drive = _record(plan, periods)
    estimated = []
    with LiveRecord(plan, target=None, last=periods) as live:
        for p in range(periods):
            before = live.batch_periods_fed
            live.add(ref[p], dut[p], drive[p], drive[p])
            assert live.batch_periods_fed - before <= 2 * BATCH_PERIODS
            count = p + 1
            assert live.due == (count <= WHOLE_RECORD_PERIODS or count in (32, 40))
            if not live.due or 1 < count < WHOLE_RECORD_PERIODS:  # (the same code as 1, 16)
                continue
            got = live.estimate()
            assert got.periods == count
            if count <= WHOLE_RECORD_PERIODS:
                expected = record_estimate(
                    ref[:count], dut[:count], plan, drive_blocks=drive[:count]
                )
            else:
                sliced = _batches(ref[:count], dut[:count], drive[:count])
                expected = record_estimate_batches(sliced, count, plan)
                assert len(live._blocks) == 0  # the record is in the spool, not in memory
            _same(got.estimate, expected.estimate)
            estimated.append(count)
            live.measured(float(np.nanmax(got.estimate.relative_type_a)))
        mean = live.mean_periods()
        fed = live.batch_periods_fed
    # without a target: 16, then twice the record until the last period
    assert estimated == [1, 16, 32, 40]
    assert fed == 32 + 40
    np.testing.assert_allclose(mean[0], ref.mean(axis=0), rtol=0, atol=1e-15)
    np.testing.assert_allclose(mean[1], dut.mean(axis=0), rtol=0, atol=1e-15)


def test_a_record_stopped_off_its_checkpoint_is_read_once_from_the_spool():
    plan = _plan()
    ref, dut, drive = _record(plan, 21)
    with LiveRecord(plan, target=None) as live:
        for p in range(21):
            live.add(ref[p], dut[p], drive[p])
            if live.due and live.count in (WHOLE_RECORD_PERIODS, 21):
                live.measured(float(np.nanmax(live.estimate().estimate.relative_type_a)))
        assert live.checkpoint == 32 and not live.due
        got = live.estimate()
    _same(got.estimate, record_estimate_batches(_batches(ref, dut, drive), 21, plan).estimate)


def test_the_work_of_a_long_record_is_linear_in_its_periods(monkeypatch):
    """Periods fed to batched records after the first 16 estimated whole, a run of 150: when
    the target is out of reach every checkpoint is twice the last (32, 64, 128, then the last
    period: 374 periods fed, under 3 P); when the type A hovers just above the target every
    checkpoint is 1/8 longer than the last (under (1 + 1/MIN_GROWTH) P + P = 10 P). O(P) in
    all whatever the type A does, and never more than two batches for one added period."""
    monkeypatch.setattr(BatchedRecord, "estimate", lambda self: None)  # the feeding counted
    plan = _plan()
    periods = 150
    ref, dut, drive = _record(plan, 1)
    for worst, bound, most in ((1.0, 374, 4), (1.00001e-3, 10 * periods, 25)):
        with LiveRecord(plan, target=1e-3, last=periods) as live:
            checkpoints = 0
            for _ in range(periods):
                before = live.batch_periods_fed
                live.add(ref[0], dut[0], drive[0])
                if live.due:
                    if live.count > WHOLE_RECORD_PERIODS:
                        live.estimate()
                        checkpoints += 1
                    live.measured(worst)
                assert live.batch_periods_fed - before <= 2 * BATCH_PERIODS
            assert live.count == periods and not live._blocks
            assert periods <= live.batch_periods_fed <= bound, (worst, live.batch_periods_fed)
            assert checkpoints <= most
