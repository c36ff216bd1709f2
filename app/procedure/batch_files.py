"""The files of a run of several DUTs (app.procedure.batch): each other member's recording
finished as the run's own (its marks, its own budget, its truth), results.json's budget and
run.log, and the batch folder's all-channel recording."""

from __future__ import annotations

import dataclasses
import json
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np

from app.io.hdf5 import Recording, RecordingWriter, Truth, read_recording
from app.records.run_folder import RunFolder
from dsp.uncertainty import Budget
from hardware.interfaces import is_dut_channel

# a batch recording's DUT channel's own skew (s), as its member run's chain states it
SKEW_ATTR = "skew_s"

if TYPE_CHECKING:
    from app.procedure import Procedure


def write_member_truth(
    procedure: Procedure, writer: RecordingWriter, sensor: Any, model: str | None
) -> None:
    """A member's simulated truth at the lines, at the excitation's rms (as the run's own)."""
    plan = procedure.plan
    rms = float(np.sqrt(np.sum(plan.amplitudes_ms2**2) / 2))
    values = sensor.sensitivity(plan.frequencies_hz, rms)
    writer.write_truth(
        Truth(
            plan.frequencies_hz,
            np.abs(values),
            np.degrees(np.angle(values)),
            {
                "dut": model or "",
                "description": procedure.stand.description,
                "level_ms2": float(procedure.identity.level_ms2 or 0.0),
                "rms_ms2": rms,
            },
        )
    )


def copy_marks(lead: Path, target: Path) -> None:
    """The run's marks on a member's recording: settle and acquired periods, mode, the
    reference's and drive's ranges (its DUT channel's range is its own, kept)."""
    with h5py.File(lead, "r") as src, h5py.File(target, "r+") as dst:
        for key in ("settle_periods", "acquired_periods", "mode"):
            if key in src.attrs:
                dst.attrs[key] = src.attrs[key]
        for name in ("reference", "drive"):  # its DUT's: its own channel's, as recorded
            if name in src["signals"] and name in dst["signals"]:
                dst["signals"][name].attrs["range_v"] = src["signals"][name].attrs["range_v"]


def own_budget(procedure: Procedure, path: Path) -> Recording:
    """A member's budget as the run makes its own (app.procedure.record_run): the stand's
    budget with its position's terms (stored when its recording opened), plus the mains hum
    from its own channel's background periods (the first periods read, drive at 0 V) and each
    line's resolution term from its own amplitudes and ranges; its "too few LSB" warnings
    (the lines it does not state) stored with it. Returns the recording as read_recording
    would read it now (its budget and warnings from the very text stored: the analysis need
    not read the file again)."""
    from app.procedure.background import BackgroundLevels, budget_with_background
    from app.procedure.ranging import run_resolution, with_resolution
    from dsp.spectral import SpectralAccumulator, period_spectrum

    recording = read_recording(path)
    plan, n = procedure.plan, recording.period_samples
    bins = np.asarray(plan.bins)
    count = max(1, procedure.settings.background_periods)
    background = SpectralAccumulator(n, plan.bins)
    power = np.zeros((2, bins.size))
    for k in range(count):
        pair = [
            np.asarray(x[k * n : (k + 1) * n], float)
            for x in (recording.reference_v, recording.dut_v)
        ]
        background.add_period(*pair)
        power += [np.abs(period_spectrum(x)[bins]) ** 2 for x in pair]
    quiet = background.estimate()
    rms = np.sqrt(power / count)
    levels = BackgroundLevels(
        quiet.reference_amplitude_v,
        quiet.dut_amplitude_v,
        quiet.reference_noise_v,
        quiet.dut_noise_v,
        rms[0],
        rms[1],
    )
    driven = SpectralAccumulator(n, plan.bins)
    reference, dut = recording.analysis_periods()
    driven.add_periods(reference, dut)
    lines = driven.estimate()
    amplitudes = (lines.reference_amplitude_v, lines.dut_amplitude_v)
    budget = budget_with_background(
        recording.budget, plan, levels, amplitudes, procedure.settings.background_periods
    )
    resolution = run_resolution(
        plan, amplitudes, levels.noise(), recording.ranges_v, procedure.stand.config.converter
    )
    budget, too_few = with_resolution(budget, resolution)
    text = json.dumps(budget.to_list())
    with h5py.File(path, "r+") as f:
        f["config"].attrs["budget"] = text
        f["config"].attrs["resolution_warnings"] = json.dumps(list(too_few))
    return dataclasses.replace(
        recording, budget=Budget.from_list(json.loads(text)), resolution_warnings=tuple(too_few)
    )


def stored_budget(path: Path) -> Budget | None:
    """The budget a member's recording stores (None: no recording, or none stored)."""
    if not path.exists():
        return None
    with h5py.File(path, "r") as f:
        text = f["config"].attrs.get("budget") if "config" in f else None
    return None if text is None else Budget.from_list(json.loads(text))


def copy_log(lead: Path, member: RunFolder) -> None:
    """The run's log (one excitation) into a member's folder."""
    source = lead / "run.log"
    if source.exists():
        with (member.path / "run.log").open("a", encoding="utf-8") as handle:
            handle.write(source.read_text(encoding="utf-8"))


def write_batch_recording(
    target: Path, lead: tuple[str, Path], others: Sequence[tuple[str, Path]]
) -> None:
    """The all-channel recording at `target`: the run's own recording (`lead`: its DUT's
    channel "dut.<position>" and recording; reference, drive, its DUT as that channel) with
    every other member's DUT channel beside it (`others`: channel, recording); no truth (each
    member's own recording holds its DUT's)."""
    channel, path = lead
    if not path.exists():  # refused before its recording opened: no signals to join
        return
    others = [(name, member) for name, member in others if member.exists()]
    shutil.copyfile(path, target)
    target.chmod(0o644)
    with h5py.File(target, "r+") as f:
        signals = f["signals"]
        signals.move("dut", channel)
        signals[channel].attrs[SKEW_ATTR] = _stored_skew(path)
        for name, member in others:
            with h5py.File(member, "r") as src:
                src.copy(src["signals/dut"], signals, name=name)
            signals[name].attrs[SKEW_ATTR] = _stored_skew(member)
        if "truth" in f:
            del f["truth"]
        f.attrs["batch_channels"] = ",".join([channel, *(name for name, _ in others)])


def _stored_skew(path: Path) -> float:
    """The skew (s) a member's recording's chain corrects its phase with (NaN: unknown)."""
    skew = read_recording(path, stored=True).chain.skew_s
    return float("nan") if skew is None else float(skew)


def channel_skew_s(path: str | Path, channel: str) -> float | None:
    """A batch recording's DUT channel's own sampling delay (s) as its member run used it;
    None when the recording does not say (written before issue 36's per-channel delays)."""
    with h5py.File(path, "r") as f:
        value = f["signals"][channel].attrs.get(SKEW_ATTR) if channel in f["signals"] else None
    if value is None or not np.isfinite(value):
        return None
    return float(value)


def batch_channels(path: str | Path) -> tuple[str, ...]:
    """The DUT channels of a batch recording ("dut.<position>" ...); () for any other."""
    with h5py.File(path, "r") as f:
        if "signals" not in f:
            return ()
        return tuple(name for name in f["signals"] if is_dut_channel(name) and name != "dut")
