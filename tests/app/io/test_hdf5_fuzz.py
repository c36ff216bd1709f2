"""Malformed HDF5 recordings through `accelcal analyze` (issue 33 point 6): a real recording (made
by `accelcal simulate`) mutated 200 times with a fixed seed (its datasets replaced, retyped,
reshaped, cut, deleted or linked away; its attributes deleted, retyped, out of range; the JSON
of its /config changed field by field) must each end in exit 2 with one line naming the dataset
or attribute that is wrong: never a traceback, never exit 1 "failed: ...".

Before this issue 9 of 200 such files ended in exit 1 (a TypeError or KeyError from the stored
JSON, an attribute of the wrong type)."""

from __future__ import annotations

import json
import random
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest

from app.cli import main

SEED = 20261127
CASES = 200

SIGNALS = ("/signals/reference", "/signals/dut", "/signals/drive")
TRUTH = ("/truth/frequency_hz", "/truth/sensitivity_mv_per_ms2", "/truth/phase_deg")
CONFIG = ("plan", "reference_chain", "budget", "cmc")
NUMERIC_ROOT = ("sample_rate_hz", "period_samples", "settle_periods", "acquired_periods")

Mutation = Callable[[random.Random, h5py.File], tuple[str, str]]  # applied: (name seen, what)


def _replace(f: h5py.File, path: str, data: Any, **kwargs: Any) -> None:
    del f[path]
    f.create_dataset(path, data=data, **kwargs)


def _dataset_mutation(rng: random.Random, f: h5py.File) -> str:
    """A signal or truth dataset replaced by one of the wrong type, shape or content."""
    path = rng.choice(SIGNALS + TRUTH)
    ds = f[path]
    values = ds[()]
    n = values.size
    kind = rng.choice(
        (
            "int",
            "text",
            "2d",
            "scalar",
            "empty",
            "cut",
            "nan",
            "inf",
            "group",
            "compound",
            "complex",
            "missing",
            "dangling",
            "unit",
        )
    )
    if path == "/signals/drive" and kind == "missing":
        kind = "cut"  # a recording may have no drive channel: its absence is no fault
    if path.startswith("/truth") and kind == "unit":
        kind = "2d"  # the truth is not in volts: it has no unit to get wrong
    if kind == "int":
        _replace(f, path, np.arange(n, dtype=np.int32))
    elif kind == "text":
        _replace(f, path, np.array([b"1.0"] * max(n, 1)))
    elif kind == "2d":
        _replace(f, path, np.resize(values, (max(n // 2, 1), 2)))
    elif kind == "scalar":
        _replace(f, path, 1.0)
    elif kind == "empty":
        _replace(f, path, np.zeros(0))
    elif kind == "cut":
        _replace(f, path, values[: max(n - rng.randint(1, 7), 0)])
    elif kind in ("nan", "inf"):
        bad = values.astype(float).copy()
        bad[rng.randrange(n)] = np.nan if kind == "nan" else -np.inf
        _replace(f, path, bad)
    elif kind == "group":
        del f[path]
        f.create_group(path)
    elif kind == "compound":
        record = np.zeros(max(n, 1), dtype=[("a", "f8"), ("b", "f8")])
        _replace(f, path, record)
    elif kind == "complex":
        _replace(f, path, values.astype(complex))
    elif kind == "missing":
        del f[path]
    elif kind == "dangling":
        del f[path]
        f[path] = h5py.SoftLink("/nowhere/at/all")
    else:  # unit: the samples in millivolts
        f[path].attrs["unit"] = rng.choice(("mV", "", "g", 5))
    return path, kind


def _range_mutation(rng: random.Random, f: h5py.File) -> str:
    """A channel's stored range that is no range in volts."""
    path = rng.choice(SIGNALS)
    value = rng.choice(("ten", np.nan, -1.0, np.inf, np.array([1.0, 2.0])))
    f[path].attrs["range_v"] = value
    return path, f"range_v {value!r}"


def _root_attribute(rng: random.Random, f: h5py.File) -> str:
    """A root attribute deleted, of the wrong type or out of range."""
    key = rng.choice((*NUMERIC_ROOT, "format_version", "mode"))
    if key == "mode":
        mode = rng.choice(("sweep", "multi sine", 3))
        f.attrs["mode"] = mode
        return "mode", repr(mode)
    bad: list[Any] = ["abc", np.nan, np.inf, -3, 2.5, np.array([1, 2]), 1e300, b"\xff\xfe"]
    if key in ("sample_rate_hz", "period_samples"):
        bad.append(None)  # None: deleted
    if key == "format_version":
        bad = ["one", 2.5, np.array([1, 1]), 99]
    value = rng.choice(bad)
    if value is None:
        del f.attrs[key]
    else:
        f.attrs[key] = value
    return key, repr(value)


def _json_paths(value: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[tuple[Any, ...], Any]]:
    """Every (path, leaf) of the numbers in a JSON value."""
    out: list[tuple[tuple[Any, ...], Any]] = []
    if isinstance(value, dict):
        for key, item in value.items():
            out += _json_paths(item, (*prefix, key))
    elif isinstance(value, list):
        for index, item in enumerate(value):
            out += _json_paths(item, (*prefix, index))
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        out.append((prefix, value))
    return out


def _set(value: Any, path: tuple[Any, ...], new: Any) -> None:
    for step in path[:-1]:
        value = value[step]
    value[path[-1]] = new


def _config_mutation(rng: random.Random, f: h5py.File) -> str:
    """A /config attribute deleted, not JSON, JSON of the wrong shape, or one number in it
    replaced by text, a list, a table, or a value out of range."""
    key = rng.choice(CONFIG)
    attrs = f["config"].attrs
    kind = rng.choice(("deleted", "garbage", "shape", "leaf", "leaf", "leaf", "deep"))
    if kind == "deleted" and key != "cmc":  # a recording may state no CMC
        del attrs[key]
    elif kind == "garbage":
        attrs[key] = rng.choice(("{", "[1, 2", "\x01", "NaN]", np.void(b"\xff\xfe{}")))
    elif kind == "shape" or kind == "deleted":
        attrs[key] = json.dumps(rng.choice(([], {}, None, 3, "text", [[1]], {"x": 1})))
    elif kind == "deep":
        attrs[key] = "[" * 100_000 + "]" * 100_000  # more nesting than a parser's stack
    else:
        data = json.loads(attrs[key])
        path, _ = rng.choice(_json_paths(data))
        new = rng.choice(("x", [1, 2], {"v": 1}, -1e308 * 10, "NaN"))
        _set(data, path, new)
        attrs[key] = json.dumps(data)
        kind = f"{'/'.join(map(str, path))} = {new!r}"
    return f"/config attribute '{key}'", kind


def _structure_mutation(rng: random.Random, f: h5py.File) -> str:
    """A group replaced by a dataset, or the signals group gone."""
    path = rng.choice(("/config", "/signals", "/truth"))
    attrs = dict(f[path].attrs) if path == "/config" else {}
    del f[path]
    f.create_dataset(path, data=np.arange(4.0))
    for key, value in attrs.items():
        f[path].attrs[key] = value
    return path, "a dataset for a group"


MUTATIONS: tuple[tuple[Mutation, int], ...] = (
    (_dataset_mutation, 8),
    (_range_mutation, 2),
    (_root_attribute, 5),
    (_config_mutation, 6),
    (_structure_mutation, 1),
)


@pytest.fixture(scope="module")
def real_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short recording of the simulated stand, written by `accelcal simulate`."""
    path = tmp_path_factory.mktemp("fuzz") / "recording.h5"
    code = main(["simulate", "--periods", "2", "--settle", "1", "--out", str(path)])
    assert code == 0 and path.is_file()
    return path


def _cases() -> list[tuple[int, Mutation]]:
    rng = random.Random(SEED)
    mutations = [m for m, w in MUTATIONS for _ in range(w)]
    return [(rng.randrange(2**32), rng.choice(mutations)) for _ in range(CASES)]


@pytest.mark.slow  # reason: 200 files through the CLI: 21 s at load 9 on two shared cores
def test_every_mutated_recording_is_refused_naming_what_is_wrong(
    real_recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    failures = []
    for number, (seed, mutate) in enumerate(_cases()):
        path = tmp_path / f"case-{number}.h5"
        shutil.copyfile(real_recording, path)
        with h5py.File(path, "r+") as f:
            expected, what = mutate(random.Random(seed), f)
        code = main(["analyze", str(path)])
        err = capsys.readouterr().err
        line = err.strip().splitlines()[-1] if err.strip() else ""
        ok = (
            code == 2
            and "Traceback" not in err
            and "failed:" not in err
            and expected in line
            and path.name in line
        )
        if not ok:
            failures.append(f"case {number} ({expected}: {what}): exit {code}: {line}")
        path.unlink()
    assert not failures, f"{len(failures)} of {CASES}:\n" + "\n".join(failures)


def test_the_fuzz_covers_every_kind_of_mutation() -> None:
    """The fixed seed draws every mutation (a change of the catalogue that drops one fails)."""
    drawn = {m.__name__ for _, m in _cases()}
    assert drawn == {m.__name__ for m, _ in MUTATIONS}


def test_the_unmutated_recording_is_analysed(real_recording: Path, capsys) -> None:
    """The fuzz's own control: the recording it mutates is itself good (exit 0)."""
    assert main(["analyze", str(real_recording)]) == 0, capsys.readouterr().err
