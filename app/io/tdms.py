"""TDMS recordings (NI LabVIEW, DAQmx logging) read with npTDMS (issue 16 point 6).

`accelcal analyze rec.tdms --reference CHANNEL --dut CHANNEL` names each channel as
"group/channel" or by a channel name found once in the file. The samples are the channels'
scaled values, in volts: a channel whose `unit_string` property names another unit is refused.
The sample rate is 1 / `wf_increment` (s), the waveform property LabVIEW and DAQmx write, equal
on both channels; a file without it needs --sample-rate. The inter-channel skew (s, positive
when the DUT channel is sampled after the reference, as --skew) is the property
`accelcal_skew_s` (`SKEW_PROPERTY`) of the DUT channel, else of its group, else of the file;
with neither it nor --skew the phase is not corrected for skew (as for CSV). The plan comes
from the options, as for CSV.

A several-DUT TDMS file (issue 36, `inspect_tdms_channels`, `read_tdms_channels`) holds a
"reference" channel, DUT channels named `dut.<position>` (found by name, or named by a mapping
from the design's DUT channel names to the file's channels) and optionally "drive"; each DUT
channel's skew is its own SKEW_PROPERTY (else its group's, else the file's). It gives one
two-channel Recording per DUT channel (app.io.channels).

Before npTDMS reads anything, the segments' lead-ins are walked: a segment that claims more
bytes than the file holds, or that its writer never closed, is refused as truncated (npTDMS
would read such a file in part and only log a warning).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from app.io.channels import (
    MAX_DUT_CHANNELS,
    MAX_IMPORT_SAMPLES,
    ImportedChannel,
    member_recordings,
)
from app.io.checks import MAX_TDMS_BYTES, InputFileError, check_dataset_size, check_input_file
from app.io.hdf5 import CHANNELS, Recording, RecordingError, merge_skew, validate
from dsp.calibration import ReferenceChain
from dsp.multisine import Plan
from dsp.uncertainty import Budget
from hardware.interfaces import is_dut_channel

log = logging.getLogger(__name__)

SKEW_PROPERTY = "accelcal_skew_s"
VOLT_UNITS = ("v", "volt", "volts")  # unit_string values read as volts (case-insensitive)
LEAD_IN_BYTES = 28  # "TDSm", ToC mask, version, next-segment offset, raw-data offset
TOC_BIG_ENDIAN = 1 << 6
UNCLOSED = (1 << 64) - 1  # next-segment offset of a segment whose writer stopped


@dataclass(frozen=True)
class TdmsSource:
    """What a TDMS file's metadata says about the two channels chosen from it."""

    path: Path
    reference: tuple[str, str]  # (group, channel)
    dut: tuple[str, str]
    samples: dict[str, int]  # per role ("reference", "dut")
    sample_rate_hz: float | None  # 1 / wf_increment; None: the file does not say
    skew_s: float | None  # SKEW_PROPERTY; None: the file does not say
    channels: tuple[str, ...]  # every channel of the file, "group/channel"


def inspect_tdms(path: str | Path, reference: str | None, dut: str | None) -> TdmsSource:
    """The file's metadata for the `reference` and `dut` channels ("group/channel" or a unique
    channel name); RecordingError naming the file, and for a channel not found (or not given)
    listing the file's channels."""
    path = Path(path)
    name = path.name
    tdms, channels, listing = _metadata(path)
    roles = {}
    for role, option, wanted in (("reference", "--reference", reference), ("dut", "--dut", dut)):
        if wanted is None:
            raise RecordingError(
                f"{option}: a TDMS recording needs it (a channel as group/channel or its "
                f"name); {name} has: {listing}"
            )
        roles[role] = _find(channels, wanted, option, name, listing)
    if roles["reference"] == roles["dut"]:
        raise RecordingError(f"--reference and --dut: both name {roles['dut']} of {name}")
    samples: dict[str, int] = {}
    increments: dict[str, float] = {}
    for role, key in roles.items():
        samples[role] = _samples(channels[key][1], f"{name}: channel {key}", key, increments)
    rate = _sample_rate(increments, name)
    dut_group, dut_channel = channels[roles["dut"]]
    skew_s = _skew(tdms, dut_group, dut_channel, roles["dut"], name)
    log.debug("%s: %s, fs %s Hz, skew %s s", name, roles, rate, skew_s)
    return TdmsSource(
        path=path,
        reference=(channels[roles["reference"]][0].name, channels[roles["reference"]][1].name),
        dut=(dut_group.name, dut_channel.name),
        samples=samples,
        sample_rate_hz=rate,
        skew_s=skew_s,
        channels=tuple(channels),
    )


def read_tdms(
    path: str | Path,
    plan: Plan,
    chain: ReferenceChain,
    budget: Budget,
    *,
    reference: str | None,
    dut: str | None,
    settle_periods: int = 0,
    range_v: float | None = None,
    source: TdmsSource | None = None,
) -> Recording:
    """Read the `reference` and `dut` channels of a TDMS file (volts) and validate them. The
    plan's sample rate must be the file's (1 / wf_increment) when the file states one; the
    file's skew property and `chain.skew_s` must agree when both are given. `source`: this
    file's inspect_tdms for these channels, when the caller has it."""
    from nptdms import TdmsFile

    if source is None or source.path != Path(path):
        source = inspect_tdms(path, reference, dut)
    name = source.path.name
    rate = source.sample_rate_hz
    if rate is not None and not math.isclose(plan.sample_rate_hz, rate, rel_tol=1e-9):
        raise RecordingError(
            f"{name}: the plan's sample rate {plan.sample_rate_hz:g} Hz differs from the file's "
            f"{rate:g} Hz (1 / wf_increment)"
        )
    chain = merge_skew(chain, source.skew_s, name, f"the file's {SKEW_PROPERTY} = {{:g}} s")
    signals = {}
    try:
        with TdmsFile.open(str(source.path)) as tdms:
            for role, (group, channel) in (("reference", source.reference), ("dut", source.dut)):
                signals[role] = np.asarray(tdms[group][channel][:], dtype=np.float64)
    except Exception as exc:  # npTDMS raises many kinds on a damaged file
        raise RecordingError(f"{name}: not a readable TDMS file ({exc})") from None
    for role, x in signals.items():
        if x.size != source.samples[role]:
            raise RecordingError(
                f"{name}: channel {'/'.join(getattr(source, role))}: {x.size} samples read of "
                f"the {source.samples[role]} its metadata states: truncated"
            )
    recording = Recording(
        sample_rate_hz=plan.sample_rate_hz,
        period_samples=plan.period_samples,
        reference_v=signals["reference"],
        dut_v=signals["dut"],
        plan=plan,
        chain=chain,
        budget=budget,
        settle_periods=settle_periods,
        ranges_v={} if range_v is None else {c: float(range_v) for c in CHANNELS},
        source=str(source.path),
    )
    validate(recording, name)
    return recording


@dataclass(frozen=True)
class TdmsChannels:
    """What a TDMS file's metadata says about the channels of a several-DUT import."""

    path: Path
    reference: tuple[str, str]  # (group, channel)
    duts: dict[str, tuple[str, str]]  # DUT channel name (dut.<position>) -> (group, channel)
    drive: tuple[str, str] | None
    samples: dict[str, int]  # per channel name: "reference", the DUT names, "drive"
    sample_rate_hz: float | None  # 1 / wf_increment; None: the file does not say
    skews_s: dict[str, float | None]  # per DUT channel, SKEW_PROPERTY; None: not stated
    channels: tuple[str, ...]  # every channel of the file, "group/channel"


def inspect_tdms_channels(
    path: str | Path,
    reference: str | None = None,
    duts: Mapping[str, str] | None = None,
    drive: str | None = None,
) -> TdmsChannels:
    """The metadata of a several-DUT TDMS file (issue 36). `reference`, `drive` and each of
    `duts`' values name a channel ("group/channel" or a unique channel name); `duts` maps the
    design's DUT channel names (dut.<position>) to them. Left out: the channel named
    "reference", every channel named as a DUT channel (dut.<position>), the channel named
    "drive" if there is one. RecordingError naming the file and the channel."""
    path = Path(path)
    name = path.name
    tdms, channels, listing = _metadata(path)
    if reference is None:
        reference = "reference"
    if duts is None:
        found = [key for key, (_, c) in channels.items() if is_dut_channel(c.name)]
        names = [channels[key][1].name for key in found]
        twice = next((n for n in names if names.count(n) > 1), None)
        if twice is not None:
            raise RecordingError(
                f"{name}: DUT channel {twice!r} is in several groups; name each as group/channel"
            )
        duts = dict(zip(names, found, strict=True))
        if not duts:
            raise RecordingError(
                f"{name}: no DUT channel (named 'dut' or 'dut.<position>'); it has: {listing}"
            )
    else:
        for channel in duts:
            if not is_dut_channel(channel):
                raise RecordingError(
                    f"{name}: DUT channel name {channel!r}: not 'dut', 'dut.<position>' or "
                    "'dut.<position>.<axis>' (position and axis: 1-16 of A-Z a-z 0-9 _ -)"
                )
        if len(duts) > MAX_DUT_CHANNELS:
            raise RecordingError(f"{name}: {len(duts)} DUT channels, more than {MAX_DUT_CHANNELS}")
    if drive is None:
        drives = [key for key, (_, c) in channels.items() if c.name == "drive"]
        drive = drives[0] if len(drives) == 1 else None
    keys = {"reference": _find(channels, reference, "reference", name, listing)}
    for channel, wanted in duts.items():
        keys[channel] = _find(channels, wanted, channel, name, listing)
    if drive is not None:
        keys["drive"] = _find(channels, drive, "drive", name, listing)
    chosen: dict[str, str] = {}
    for role, key in keys.items():
        if key in chosen:
            raise RecordingError(f"{name}: {chosen[key]} and {role} both name {key}")
        chosen[key] = role
    samples: dict[str, int] = {}
    increments: dict[str, float] = {}
    for role, key in keys.items():
        where = f"{name}: channel {key} ({role})"
        samples[role] = _samples(channels[key][1], where, key, increments)
    if sum(samples.values()) > MAX_IMPORT_SAMPLES:
        raise RecordingError(
            f"{name}: {sum(samples.values())} samples in the {len(samples)} channels: more "
            f"than an import may hold ({MAX_IMPORT_SAMPLES})"
        )
    skews = {
        role: _skew(tdms, channels[key][0], channels[key][1], key, name)
        for role, key in keys.items()
        if role not in ("reference", "drive")
    }

    def pair(key: str) -> tuple[str, str]:
        return channels[key][0].name, channels[key][1].name

    return TdmsChannels(
        path=path,
        reference=pair(keys["reference"]),
        duts={role: pair(key) for role, key in keys.items() if role in skews},
        drive=pair(keys["drive"]) if "drive" in keys else None,
        samples=samples,
        sample_rate_hz=_sample_rate(increments, name),
        skews_s=skews,
        channels=tuple(channels),
    )


def read_tdms_channels(
    path: str | Path,
    plan: Plan,
    chain: ReferenceChain,
    budget: Budget,
    *,
    reference: str | None = None,
    duts: Mapping[str, str] | None = None,
    drive: str | None = None,
    settle_periods: int = 0,
    range_v: float | None = None,
    source: TdmsChannels | None = None,
) -> dict[str, Recording]:
    """Read a several-DUT TDMS file (inspect_tdms_channels names its channels): per DUT
    channel its two-channel Recording (app.io.channels.member_recordings), each with that
    channel's skew. The plan's sample rate must be the file's when the file states one."""
    from nptdms import TdmsFile

    if source is None or source.path != Path(path):
        source = inspect_tdms_channels(path, reference, duts, drive)
    name = source.path.name
    rate = source.sample_rate_hz
    if rate is not None and not math.isclose(plan.sample_rate_hz, rate, rel_tol=1e-9):
        raise RecordingError(
            f"{name}: the plan's sample rate {plan.sample_rate_hz:g} Hz differs from the file's "
            f"{rate:g} Hz (1 / wf_increment)"
        )
    wanted = {"reference": source.reference, **source.duts}
    if source.drive is not None:
        wanted["drive"] = source.drive
    signals = {}
    try:
        with TdmsFile.open(str(source.path)) as tdms:
            for role, (group, channel) in wanted.items():
                signals[role] = np.asarray(tdms[group][channel][:], dtype=np.float64)
    except Exception as exc:  # npTDMS raises many kinds on a damaged file
        raise RecordingError(f"{name}: not a readable TDMS file ({exc})") from None
    for role, x in signals.items():
        if x.size != source.samples[role]:
            raise RecordingError(
                f"{name}: channel {'/'.join(wanted[role])}: {x.size} samples read of the "
                f"{source.samples[role]} its metadata states: truncated"
            )
    label = {role: f"{'/'.join(key)} ({role})" for role, key in wanted.items()}
    members = {
        role: ImportedChannel(signals[role], source.skews_s[role], label[role])
        for role in source.duts
    }
    return member_recordings(
        name,
        plan,
        chain,
        budget,
        reference_v=signals["reference"],
        duts=members,
        drive_v=signals.get("drive"),
        labels={"reference": label["reference"], "drive": label.get("drive", "drive")},
        settle_periods=settle_periods,
        range_v=range_v,
        source=str(source.path),
        skew_where=f"the file's {SKEW_PROPERTY} of {{channel}} = {{{{:g}}}} s",
    )


def _metadata(path: Path) -> tuple[Any, dict[str, Any], str]:
    """The file's metadata (npTDMS), its channels by "group/channel" and their listing, after
    the size and segment checks; RecordingError naming the file."""
    from nptdms import TdmsFile

    name = path.name
    try:
        size = check_input_file(path, MAX_TDMS_BYTES, "TDMS recording")
    except InputFileError as exc:
        raise RecordingError(str(exc)) from None
    check_segments(path, size)
    try:
        tdms = TdmsFile.read_metadata(str(path))
    except Exception as exc:  # npTDMS raises many kinds on a damaged file
        raise RecordingError(f"{name}: not a readable TDMS file ({exc})") from None
    channels = {f"{g.name}/{c.name}": (g, c) for g in tdms.groups() for c in g.channels()}
    return tdms, channels, ", ".join(channels) or "none"


def check_segments(path: Path, size: int) -> None:
    """Walk the segments' lead-ins: RecordingError naming the file when it is not TDMS, when a
    segment reaches past the end of the file, or when one was never closed (truncated)."""
    name = path.name
    if size == 0:
        raise RecordingError(f"{name}: empty, not a TDMS file")
    try:
        with path.open("rb") as f:
            position = 0
            while position < size:
                f.seek(position)
                lead_in = f.read(LEAD_IN_BYTES)
                if lead_in[:4] != b"TDSm":
                    if position == 0:
                        raise RecordingError(f"{name}: not a TDMS file (no 'TDSm' tag at start)")
                    raise RecordingError(
                        f"{name}: no segment at byte {position} where the previous one ends: "
                        "damaged or truncated"
                    )
                if len(lead_in) < LEAD_IN_BYTES:
                    raise RecordingError(
                        f"{name}: truncated: the segment at byte {position} ends inside its lead-in"
                    )
                toc = int.from_bytes(lead_in[4:8], "little")
                order: Literal["little", "big"] = "big" if toc & TOC_BIG_ENDIAN else "little"
                following = int.from_bytes(lead_in[12:20], order)
                if following == UNCLOSED:
                    raise RecordingError(
                        f"{name}: truncated: the segment at byte {position} was never closed "
                        "(its writer stopped)"
                    )
                end = position + LEAD_IN_BYTES + following
                if end > size:
                    raise RecordingError(
                        f"{name}: truncated: the segment at byte {position} needs {end} bytes, "
                        f"the file has {size}"
                    )
                position = end
    except OSError as exc:
        raise RecordingError(f"{name}: cannot be read ({exc})") from None


def _samples(channel: Any, where: str, key: str, increments: dict[str, float]) -> int:
    """A chosen channel's sample count, refused (naming `where`) when it does not hold numbers
    in volts or holds more than a recording may; its wf_increment (s) into `increments`."""
    kind = np.dtype(channel.dtype).kind if channel.dtype is not None else "?"
    if kind not in "fiu":
        raise RecordingError(f"{where}: holds {channel.dtype} data, not samples in volts")
    unit = channel.properties.get("unit_string")
    if unit is not None and str(unit).strip().lower() not in VOLT_UNITS:
        raise RecordingError(f"{where}: unit_string {unit!r}; the samples must be in volts (V)")
    count = len(channel)
    try:
        check_dataset_size(count, where)
    except InputFileError as exc:
        raise RecordingError(str(exc)) from None
    if "wf_increment" in channel.properties:
        increments[key] = _number(channel.properties["wf_increment"], f"{where}: wf_increment")
    return count


def _skew(tdms: Any, group: Any, channel: Any, key: str, name: str) -> float | None:
    """SKEW_PROPERTY (s) of the channel, else of its group, else of the file; None without."""
    for holder, obj in (
        (f"channel {key}", channel),
        (f"group {group.name}", group),
        ("the file", tdms),
    ):
        if SKEW_PROPERTY in obj.properties:
            where = f"{name}: {SKEW_PROPERTY} of {holder}"
            skew_s = _number(obj.properties[SKEW_PROPERTY], where)
            if abs(skew_s) > 1.0:
                raise RecordingError(f"{where}: {skew_s:g} is not a delay in s (within +-1 s)")
            return skew_s
    return None


def _find(channels: dict[str, Any], wanted: str, option: str, name: str, listing: str) -> str:
    """The "group/channel" key `wanted` names: itself, or the one channel of that name."""
    if wanted in channels:
        return wanted
    matches = [key for key, (_, channel) in channels.items() if channel.name == wanted]
    if len(matches) == 1:
        return matches[0]
    if matches:
        raise RecordingError(
            f"{option}: {wanted!r} names {len(matches)} channels of {name} "
            f"({', '.join(matches)}); give it as group/channel"
        )
    raise RecordingError(f"{option}: no channel {wanted!r} in {name}; it has: {listing}")


def _number(value: object, where: str) -> float:
    """A property's value as a finite float; RecordingError naming it otherwise."""
    if isinstance(value, bool | str | bytes) or not isinstance(value, int | float | np.number):
        raise RecordingError(f"{where}: {value!r} is not a number")
    number = float(value)
    if not math.isfinite(number):
        raise RecordingError(f"{where}: {number!r} is not finite")
    return number


def _sample_rate(increments: dict[str, float], name: str) -> float | None:
    """1 / wf_increment (Hz) of the channels that state it (equal on all), None without."""
    if not increments:
        return None
    values = list(increments.values())
    for key, value in increments.items():
        if not value > 0:
            raise RecordingError(f"{name}: channel {key}: wf_increment {value:g} s is not > 0")
        if not math.isclose(value, values[0], rel_tol=1e-9):
            detail = ", ".join(f"{k} {v:g} s" for k, v in increments.items())
            raise RecordingError(f"{name}: the channels' wf_increment differ ({detail})")
    rate = 1.0 / values[0]
    rounded = round(rate, 6)  # 1 / (1 / 6000) is 6000.000000000001: to the microhertz
    return rounded if math.isclose(rounded, rate, rel_tol=1e-12) else rate
