"""The fields of an HDF5 recording read as typed values, each refused by name when it is not
what this program writes (issue 33 point 6): a root attribute of the wrong type or out of range,
a /config attribute that is not the JSON of its object, a dataset that is missing, linked away,
a group, not 1-D or not floating point. The refusal (`RecordingError`) names the file and the
dataset or attribute; nothing here lets a TypeError or KeyError of a malformed file escape.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import h5py
import numpy as np

from app.errors import Refusal
from app.io.checks import InputFileError, check_dataset_size
from app.io.vocabulary import Mode
from dsp.calibration import ReferenceChain
from dsp.multisine import Plan

T = TypeVar("T")

# what a malformed stored object can raise from its own parser: each becomes a refusal
PARSE_ERRORS = (
    ValueError,
    TypeError,
    KeyError,
    IndexError,
    AttributeError,
    RecursionError,
    OverflowError,
)
MAX_JSON_CHARS = 4 << 20  # a /config attribute: 4 MiB of text at most


class RecordingError(Refusal):
    """A recording that cannot be analysed; the message names the file and the problem."""


def _scalar(value: Any) -> Any:
    """A one-element numpy value or array as its Python scalar; anything else unchanged."""
    if isinstance(value, np.ndarray) and value.size == 1:
        value = value.reshape(()).item()
    elif isinstance(value, np.generic):
        value = value.item()
    return value


def text_attr(attrs: h5py.AttributeManager, key: str, where: str) -> str | None:
    """The text attribute `key` (None when absent); bytes must be UTF-8."""
    if key not in attrs:
        return None
    value = _scalar(attrs[key])
    if isinstance(value, bytes):
        try:
            value = value.decode("utf-8")
        except UnicodeDecodeError:
            raise RecordingError(f"{where} '{key}': not UTF-8 text") from None
    if not isinstance(value, str):
        raise RecordingError(f"{where} '{key}': {value!r} is not text")
    return value


def number_attr(
    attrs: h5py.AttributeManager,
    key: str,
    where: str,
    *,
    low: float,
    high: float,
    whole: bool = False,
    open_low: bool = False,
) -> float | None:
    """The number attribute `key` (None when absent): a finite real scalar in [low, high]
    ((low, high] with `open_low`), a whole number when `whole`."""
    if key not in attrs:
        return None
    value = _scalar(attrs[key])
    kind = "a whole number" if whole else "a number"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise RecordingError(f"{where} '{key}': {_short(value)} is not {kind}")
    number = float(value)
    if not math.isfinite(number) or (whole and number != int(number)):
        raise RecordingError(f"{where} '{key}': {number!r} is not {kind}")
    too_low = number <= low if open_low else number < low
    if too_low or number > high:
        left = "(" if open_low else "["
        raise RecordingError(f"{where} '{key}': {number:g} is not in {left}{low:g}, {high:g}]")
    return number


def json_attr(
    attrs: h5py.AttributeManager, key: str, where: str, parse: Callable[[Any], T]
) -> T | None:
    """The /config attribute `key` (None when absent) as JSON text given to `parse`; every
    failure of the text or of `parse` refused naming the attribute."""
    text = text_attr(attrs, key, where)
    if text is None:
        return None
    name = f"{where} '{key}'"
    if len(text) > MAX_JSON_CHARS:
        raise RecordingError(f"{name}: {len(text)} characters is more than a recording may hold")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RecordingError(f"{name} is not valid JSON ({exc})") from None
    except RecursionError:
        raise RecordingError(f"{name} is not valid JSON (nested too deeply)") from None
    try:
        return parse(data)
    except PARSE_ERRORS as exc:
        detail = str(exc) or type(exc).__name__
        raise RecordingError(f"{name}: {detail}") from None


def float_dataset(
    f: h5py.File, path: str, name: str, *, optional: bool = False
) -> h5py.Dataset | None:
    """The 1-D floating-point dataset at `path` (None when absent and `optional`), refused
    when it is missing, a link to nothing or to another file, a group, not 1-D, not floating
    point, larger than a recording may hold, or stored outside the file. The message names
    the file (`name`) and the dataset."""
    label = f"{name}: /{path}"
    link = f.get(path, getlink=True)
    if link is None:
        if optional:
            return None
        raise RecordingError(f"{name}: missing dataset /{path}")
    if isinstance(link, h5py.ExternalLink):
        raise RecordingError(f"{label}: a link to another file; a recording holds its samples")
    try:
        ds = f.get(path)
    except (KeyError, OSError, RuntimeError, ValueError) as exc:
        raise RecordingError(f"{label}: cannot be opened ({exc})") from None
    if ds is None:
        raise RecordingError(f"{label}: a link to nothing ({getattr(link, 'path', '?')})")
    if not isinstance(ds, h5py.Dataset):
        raise RecordingError(f"{label}: a group where a 1-D dataset belongs")
    if ds.ndim != 1:
        raise RecordingError(f"{label}: shape {ds.shape}, expected a 1-D dataset")
    if ds.external or ds.is_virtual:
        raise RecordingError(
            f"{label}: dataset stored outside the file (external or virtual storage); a "
            "recording holds its samples itself"
        )
    if ds.dtype.kind != "f":
        raise RecordingError(f"{label}: dataset of type {ds.dtype}, expected floating point")
    try:
        check_dataset_size(int(ds.size), label)
    except InputFileError as exc:
        raise RecordingError(str(exc)) from None
    return ds


def group(f: h5py.File, path: str, name: str, *, optional: bool = False) -> h5py.Group | None:
    """The group at `path` (None when absent and `optional`), refused naming the file (`name`)
    and the group when it is a dataset, a link to nothing or missing."""
    label = f"{name}: /{path}"
    link = f.get(path, getlink=True)
    if link is None:
        if optional:
            return None
        raise RecordingError(f"{name}: missing group /{path}")
    try:
        found = f.get(path)
    except (KeyError, OSError, RuntimeError, ValueError) as exc:
        raise RecordingError(f"{label}: cannot be opened ({exc})") from None
    if not isinstance(found, h5py.Group):
        raise RecordingError(f"{label}: {'a dataset' if found is not None else 'nothing'} "
                             "where a group belongs")  # fmt: skip
    return found


@dataclass(frozen=True)
class Head:
    """The root attributes a recording is read by (Hz, samples, periods)."""

    sample_rate_hz: float
    period_samples: int
    settle_periods: int
    acquired_periods: int | None


MAX_PERIOD_SAMPLES = 2**25  # a dataset holds at most this many samples (app.io.checks)


def read_head(f: h5py.File, name: str, format_name: str, format_version: int) -> Head:
    """The root attributes, each checked by name (`format_name`, at most `format_version`):
    format, format_version, mode, sample rate,
    period, settle and acquired periods."""
    where = f"{name}: attribute"
    if text_attr(f.attrs, "format", where) != format_name:
        raise RecordingError(f"{name}: not an {format_name} file (attribute 'format')")
    mode = text_attr(f.attrs, "mode", where) or Mode.MULTISINE.value
    if mode == Mode.STEPPED_SINE:
        raise RecordingError(
            f"{name}: a stepped-sine recording (blocks of different lengths per line); its "
            "results are in the run's results.json, re-analysis is for multisine recordings"
        )
    if mode not in tuple(Mode):
        raise RecordingError(f"{where} 'mode': {mode!r} is not one of {', '.join(Mode)}")
    version = number_attr(f.attrs, "format_version", where, low=-1, high=1e9, whole=True)
    if version is not None and version > format_version:
        raise RecordingError(
            f"{where} 'format_version': {version:g} is newer than this program's {format_version}"
        )
    bounds: dict[str, tuple[float, float, bool]] = {
        "sample_rate_hz": (0.0, 1e9, False),
        "period_samples": (2, MAX_PERIOD_SAMPLES, True),
        "settle_periods": (0, MAX_PERIOD_SAMPLES, True),
        "acquired_periods": (0, MAX_PERIOD_SAMPLES, True),
    }
    values: dict[str, float | None] = {}
    for key, (low, high, whole) in bounds.items():
        values[key] = number_attr(
            f.attrs, key, where, low=low, high=high, whole=whole, open_low=key == "sample_rate_hz"
        )
    for key in ("sample_rate_hz", "period_samples"):
        if values[key] is None:
            raise RecordingError(f"{name}: missing attribute '{key}'")
    acquired = values["acquired_periods"]
    return Head(
        float(values["sample_rate_hz"] or 0.0),
        int(values["period_samples"] or 0),
        int(values["settle_periods"] or 0),
        None if acquired is None else int(acquired),
    )


def plan_from(data: Any) -> Plan:
    """The stored plan (a JSON object) with every line's numbers finite and its amplitudes
    > 0; PlanError, ValueError or TypeError say what is wrong."""
    if not isinstance(data, dict):
        raise TypeError(f"a JSON object expected, got {type(data).__name__}")
    version = data.get("format_version", 1)
    if isinstance(version, bool) or not isinstance(version, int) or version != 1:
        raise ValueError(f"format_version {version!r} is not 1")
    plan = Plan.from_dict(data)
    for line in plan.lines:
        numbers = (line.amplitude_ms2, line.phase_rad, line.frequency_hz)
        if not all(math.isfinite(v) for v in numbers) or line.amplitude_ms2 <= 0:
            raise ValueError(f"line {line.label}: amplitude and phase must be finite, > 0")
    return plan


def chain_from(data: Any) -> ReferenceChain:
    if not isinstance(data, dict):
        raise TypeError(f"a JSON object expected, got {type(data).__name__}")
    return ReferenceChain.from_dict(data)


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."
