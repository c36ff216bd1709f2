"""An imported recording with N DUT channels (issue 36 point 4): the channel names, and one
two-channel Recording per DUT channel.

A several-DUT recording (CSV or TDMS) holds a "reference" channel, DUT channels named
`dut.<position>` (a triaxial DUT's `dut.<position>.<axis>`) and optionally "drive". Each DUT
is estimated on the pair (reference, its channel) with the same estimator code as a single-DUT
run, so the import gives, per DUT channel, the Recording a single-DUT import gives: its
`dut_v` that channel, `reference_v` and `drive_v` shared (the same arrays, not copies), its
chain's skew that channel's own. `analyze` runs on each as on a single-DUT recording.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from app.io.checks import MAX_RECORDING_SAMPLES
from app.io.hdf5 import CHANNELS, Recording, RecordingError, merge_skew, validate
from dsp.calibration import ReferenceChain
from dsp.multisine import Plan
from dsp.uncertainty import Budget
from hardware.interfaces import is_dut_channel  # the design's DUT channel names

# Samples of all the channels an import holds together: today's three channels' worth, so a
# several-DUT import takes no more memory than the largest single-DUT one.
MAX_IMPORT_SAMPLES = 3 * MAX_RECORDING_SAMPLES
MAX_DUT_CHANNELS = 32  # more than any DAQ's analog inputs this program drives


@dataclasses.dataclass(frozen=True)
class ImportedChannel:
    """One DUT channel as read: its samples (V), its skew after the reference (s; None: the
    file states none) and where it came from (a column or a TDMS channel, for messages)."""

    samples: np.ndarray
    skew_s: float | None
    label: str


def member_recordings(
    name: str,
    plan: Plan,
    chain: ReferenceChain,
    budget: Budget,
    *,
    reference_v: np.ndarray,
    duts: Mapping[str, ImportedChannel],
    drive_v: np.ndarray | None = None,
    labels: Mapping[str, str] | None = None,
    settle_periods: int = 0,
    range_v: float | None = None,
    source: str = "",
    skew_where: str = "the file's skew of {channel} = {{:g}} s",
) -> dict[str, Recording]:
    """Per DUT channel (in `duts`' order) its validated two-channel Recording; RecordingError
    naming the file and the channel (`labels`: where the reference and drive came from). The
    chain's skew (--skew) must agree with each channel's own when both are given."""
    if not duts:
        raise RecordingError(f"{name}: no DUT channel ('dut' or 'dut.<position>')")
    ranges = {} if range_v is None else {c: float(range_v) for c in CHANNELS}
    labels = dict(labels or {})
    out: dict[str, Recording] = {}
    for channel, dut in duts.items():
        member_chain = merge_skew(chain, dut.skew_s, name, skew_where.format(channel=channel))
        recording = Recording(
            sample_rate_hz=plan.sample_rate_hz,
            period_samples=plan.period_samples,
            reference_v=reference_v,
            dut_v=dut.samples,
            drive_v=drive_v,
            plan=plan,
            chain=member_chain,
            budget=budget,
            settle_periods=settle_periods,
            ranges_v=ranges,
            source=f"{source}#{channel}" if source else channel,
        )
        validate(recording, name, labels={**labels, "dut": dut.label})
        out[channel] = recording
    return out


def check_names(names: list[str], where: str, what: str) -> None:
    """Refuse a set of channel names that is not one "reference", DUT channels by the design's
    names (at least one, at most MAX_DUT_CHANNELS), at most one "drive", each once; the message
    names the offending channel (`what`: "column", "channel")."""
    seen: set[str] = set()
    for index, channel in enumerate(names, start=1):
        if channel in seen:
            raise RecordingError(f"{where}: {what} {index} {channel!r}: named twice")
        seen.add(channel)
        if channel not in ("reference", "drive") and not is_dut_channel(channel):
            raise RecordingError(
                f"{where}: {what} {index} {channel!r}: not a channel name (reference, "
                "dut.<position>, dut.<position>.<axis> or drive)"
            )
    if "reference" not in seen:
        raise RecordingError(f"{where}: no {what} named 'reference'")
    duts = [c for c in names if is_dut_channel(c)]
    if not duts:
        raise RecordingError(f"{where}: no DUT {what} ('dut' or 'dut.<position>')")
    if len(duts) > MAX_DUT_CHANNELS:
        raise RecordingError(f"{where}: {len(duts)} DUT {what}s, more than {MAX_DUT_CHANNELS}")
