"""The store of measured stand responses (app.stand.response, issue 14 point 1): keyed by stand
hash, simulated realisation, mode, DUT mass class and plan lines; age limit; nearest level; a
damaged file ignored, never fatal."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta

import numpy as np
import pytest

from app.stand.response import (
    MASS_UNSTATED,
    ResponseStore,
    StoredResponse,
    mass_class,
    stand_sha256,
)
from dsp.crestfactor import schroeder_phases
from dsp.multisine import make_plan

NOW = datetime(2026, 11, 24, 12, 0, tzinfo=UTC)


def _plan(frequencies: list[float], period: int = 12000, level: float = 5.0):
    """A 6 kS/s plan with Schroeder's phases (the store keys by lines, not by how the phases
    were found: no optimisation while the tests are collected)."""
    phases = schroeder_phases(np.ones(len(frequencies)))
    return make_plan(frequencies, 6000.0, period, level, 160.0, phases_rad=list(phases))


PLAN = _plan([10.0, 80.0, 160.0, 1000.0])
STAND = stand_sha256("[daq]\nbackend = 'sim'\n")


def entry(level: float = 5.0, *, days_old: float = 1.0, mass: str = "up to 25 g", **kw):
    values = dict(
        stand_sha256=STAND,
        realisation="seed 1",
        mode="multisine",
        mass_class=mass,
        sample_rate_hz=6000.0,
        period_samples=12000,
        bins=tuple(int(b) for b in PLAN.bins),
        levels_ms2=(level,) * 4,
        phases_rad=tuple(float(p) for p in PLAN.phases_rad),
        response=np.array([1 + 2j, 3 - 1j, 4 + 0.5j, -2 + 1j]) * level,
        measured_utc=(NOW - timedelta(days=days_old)).isoformat(timespec="seconds"),
        run_id=f"run-{level:g}",
        worst_error=0.001,
    )
    values.update(kw)
    return StoredResponse(**values)  # type: ignore[arg-type]


def lookup(store: ResponseStore, *, mass="up to 25 g", mode="multisine", plan=PLAN, age=30.0):
    return store.lookup(STAND, "seed 1", mode, mass, plan, now=NOW, max_age_days=age)


def test_mass_classes_have_their_stated_bounds():
    assert mass_class(None) == MASS_UNSTATED
    assert mass_class(0.0) == mass_class(25.0) == "up to 25 g"
    assert mass_class(25.001) == mass_class(100.0) == "25-100 g"
    assert mass_class(100.5) == "100-300 g"
    assert mass_class(301.0) == "over 300 g"
    with pytest.raises(ValueError, match="DUT mass"):
        mass_class(-1.0)
    with pytest.raises(ValueError, match="DUT mass"):
        mass_class(float("nan"))


def test_a_saved_response_is_found_again_exactly(tmp_path):
    store = ResponseStore(tmp_path)
    saved = entry()
    store.save(saved)
    found = lookup(store)
    assert found.entry is not None
    np.testing.assert_array_equal(found.entry.response, saved.response)
    assert found.entry.measured_utc == "2026-11-23T12:00:00+00:00"
    assert "run-5" in found.reason and "1.0 days old" in found.reason


@pytest.mark.parametrize(
    ("change", "why"),
    [
        ({"mass": "100-300 g"}, "no stored response"),
        ({"mode": "stepped-sine"}, "no stored response"),
        ({"plan": _plan([10.0, 80.0, 160.0, 1250.0])}, "no stored"),
        ({"plan": _plan([10.0, 80.0, 160.0, 1000.0], period=6000)}, "no stored"),
        ({"age": 0.5}, "older than 0.5 days"),
    ],
)
def test_another_mass_class_mode_plan_or_an_old_response_is_not_used(tmp_path, change, why):
    store = ResponseStore(tmp_path)
    store.save(entry())
    found = lookup(store, **change)
    assert found.entry is None
    assert why in found.reason


def test_another_stand_or_realisation_finds_nothing(tmp_path):
    store = ResponseStore(tmp_path)
    store.save(entry())
    other = stand_sha256("[daq]\nbackend = 'sim'\n# edited\n")
    assert store.lookup(other, "seed 1", "multisine", "up to 25 g", PLAN, now=NOW,
                        max_age_days=30).entry is None  # fmt: skip
    assert store.lookup(STAND, "seed 2", "multisine", "up to 25 g", PLAN, now=NOW,
                        max_age_days=30).entry is None  # fmt: skip


def test_the_nearest_level_is_used_and_a_same_level_entry_is_replaced(tmp_path):
    store = ResponseStore(tmp_path)
    for level in (3.0, 5.0, 7.0):
        store.save(entry(level))
    store.save(entry(5.0, days_old=0.0, run_id="newer"))  # replaces the 5 m/s^2 one
    found = lookup(store)  # the plan is at 5 m/s^2 per line
    assert found.entry is not None and found.entry.run_id == "newer"
    data = json.loads(next(tmp_path.rglob("*.json")).read_text())
    assert sorted(e["levels_ms2"][0] for e in data["entries"]) == [3.0, 5.0, 7.0]
    at_6 = _plan([10.0, 80.0, 160.0, 1000.0], level=6.5)
    nearest = lookup(store, plan=at_6).entry
    assert nearest is not None and nearest.levels_ms2[0] == 7.0  # |ln 7/6.5| < |ln 5/6.5|


@pytest.mark.parametrize(
    "damage",
    [
        "not json at all",
        json.dumps({"format": 99, "entries": []}),
        json.dumps({"format": 1, "entries": [{"bins": [1]}]}),
        "DAMAGED-RESPONSE",
    ],
)
def test_a_damaged_store_file_is_ignored_not_fatal(tmp_path, damage, caplog):
    store = ResponseStore(tmp_path)
    path = store.save(entry())
    if damage == "DAMAGED-RESPONSE":  # a zero response would divide the drive by zero
        data = json.loads(path.read_text())
        data["entries"][0]["response_real"][1] = 0.0
        data["entries"][0]["response_imag"][1] = 0.0
        damage = json.dumps(data)
    path.write_text(damage)
    found = lookup(store)
    assert found.entry is None
    assert "ignored" in caplog.text or "unreadable" in caplog.text


def test_saving_leaves_no_temporary_file(tmp_path):
    store = ResponseStore(tmp_path)
    store.save(entry())
    store.save(entry(6.0))
    names = [p.name for p in tmp_path.rglob("*") if p.is_file()]
    assert len(names) == 1 and not names[0].startswith(".response-")


# --- issue 25 point 7: the store file is read with stat-before-open and a size bound --------


def _store_path(store: ResponseStore):
    path = store.save(entry())
    good = path.read_bytes()
    path.unlink()
    return path, good


def _no_hang(seconds: int = 5):
    import signal

    def fail(*_):
        raise AssertionError("the read blocked")

    signal.signal(signal.SIGALRM, fail)
    signal.alarm(seconds)


def test_a_fifo_in_place_of_the_store_file_is_refused_without_blocking(tmp_path, caplog):
    import os
    import signal

    store = ResponseStore(tmp_path)
    path, _ = _store_path(store)
    os.mkfifo(path)  # nobody writes: a plain open() would block forever
    _no_hang()
    try:
        found = lookup(store)
    finally:
        signal.alarm(0)
    assert found.entry is None
    assert "not a regular file" in caplog.text


def test_dev_zero_in_place_of_the_store_file_is_refused(tmp_path, caplog):
    store = ResponseStore(tmp_path)
    path, _ = _store_path(store)
    path.symlink_to("/dev/zero")  # read() would return zeros without end
    _no_hang()
    try:
        found = lookup(store)
    finally:
        import signal

        signal.alarm(0)
    assert found.entry is None
    assert "not a regular file" in caplog.text


def test_a_symlink_to_a_good_store_file_is_refused(tmp_path, caplog):
    store = ResponseStore(tmp_path)
    path, good = _store_path(store)
    elsewhere = tmp_path / "elsewhere.json"
    elsewhere.write_bytes(good)
    path.symlink_to(elsewhere)
    assert lookup(store).entry is None
    assert "not a regular file" in caplog.text
    path.unlink()
    path.write_bytes(good)  # the same bytes as a regular file are read
    found = lookup(store).entry
    assert found is not None and np.array_equal(found.response, entry().response)


def test_an_oversized_store_file_is_refused_by_its_size(tmp_path, caplog):
    from app.stand.response import MAX_STORE_BYTES, read_store_file

    store = ResponseStore(tmp_path)
    path, good = _store_path(store)
    path.write_bytes(good + b" " * (MAX_STORE_BYTES + 1 - len(good)))
    assert lookup(store).entry is None
    assert f"over the {MAX_STORE_BYTES} byte bound" in caplog.text
    path.write_bytes(good)
    assert read_store_file(path) == good
    with pytest.raises(ValueError, match="over the 10 byte bound"):
        read_store_file(path, max_bytes=10)
