"""Issue 31 points 7-8: a plan's optimised phases come from the shipped data (presets) or the
user's data directory (custom plans), equal to what the optimiser computes, never trusted
blindly (app.procedure.phase_store)."""

from __future__ import annotations

import functools
import json
import logging
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from app.procedure import phase_store
from app.procedure.phase_store import PhaseKey, stored_phases
from app.procedure.planning import PlanRequest, build_plan
from app.procedure.service import RunService
from dsp import crestfactor
from dsp.multisine import PRESETS, preset_plan

CUSTOM_BINS = np.array([3, 5, 8, 13, 21])
CUSTOM_AMPS = np.array([1.0, 0.8, 0.5, 0.3, 0.2])
CUSTOM_N = 128
OPTIMISE = crestfactor.optimise_phases  # the real one, whatever a test counts


@pytest.fixture()
def data(tmp_path, monkeypatch) -> Path:
    """A data directory of the test's own."""
    monkeypatch.setenv("ACCELCAL_DATA_DIR", str(tmp_path / "data"))
    return tmp_path / "data"


@pytest.fixture()
def optimiser_calls(monkeypatch) -> list[tuple]:
    """Every call of the real optimiser from here on (it still runs)."""
    real, calls = crestfactor.optimise_phases, []

    def counted(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(crestfactor, "optimise_phases", counted)
    return calls


@functools.cache
def _optimised(seed: int) -> bytes:
    return OPTIMISE(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N, seed=seed).tobytes()


def _real(seed: int = 0) -> np.ndarray:
    """What the real optimiser gives for the custom plan (computed once per test process)."""
    return np.frombuffer(_optimised(seed))


@pytest.fixture(scope="module")
def custom_entry(tmp_path_factory) -> tuple[str, str]:
    """The cache entry the product writes for the custom plan: its file name and text
    (made once; a test copies it into its own data directory)."""
    with pytest.MonkeyPatch.context() as patch:
        folder = tmp_path_factory.mktemp("custom-entry")
        patch.setenv("ACCELCAL_DATA_DIR", str(folder))
        stored_phases(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N)
        (path,) = (folder / "phases").iterdir()
        return path.name, path.read_text()


def _with_entry(data: Path, entry: tuple[str, str]) -> None:
    (data / "phases").mkdir(parents=True)
    (data / "phases" / entry[0]).write_text(entry[1])


def _cache_file(data: Path) -> Path:
    (path,) = (data / "phases").iterdir()
    return path


# --- the shipped phases -----------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(PRESETS))
def test_the_shipped_phases_are_what_the_optimiser_computes_today(name):
    """Fails after a change to dsp/crestfactor.py or a preset until `make phases` is run."""
    key = phase_store.preset_keys()[name]
    document = json.loads((phase_store.shipped_folder() / f"{name}.json").read_text())
    shipped = phase_store.trusted(document, key)
    real = crestfactor.optimise_phases(
        np.array(key.bins), np.ones(len(key.bins)), key.period_samples, seed=0
    )
    assert shipped.tobytes() == real.tobytes()
    plan = preset_plan(name)  # the plan as dsp makes it, optimising
    assert plan.phases_rad.tobytes() == real.tobytes()


def test_every_preset_has_shipped_phases_in_the_package():
    assert set(phase_store._shipped()) == {k.digest for k in phase_store.preset_keys().values()}


def test_the_product_makes_a_preset_plan_without_optimising(data, monkeypatch):
    def refuse(*_args, **_kwargs):
        raise AssertionError("optimised although the phases are shipped")

    monkeypatch.setattr(crestfactor, "optimise_phases", refuse)
    shipped = phase_store._shipped()
    for name in PRESETS:
        digest = phase_store.preset_keys()[name].digest
        plan = build_plan(PlanRequest(preset=name, level_ms2=3.7))  # accelcal plan/run, GUI
        assert plan.phases_rad.tobytes() == shipped[digest].tobytes()
        also = preset_plan(name, level_ms2=0.2, optimiser=stored_phases)  # request, simulate
        assert also.phases_rad.tobytes() == shipped[digest].tobytes()
    service = RunService()  # the simulated stand: the GUI's plans, at once for every preset
    for key in service.preset_keys():
        digest = phase_store.preset_keys()[key.preset].digest
        assert service.unit_plan(key).phases_rad.tobytes() == shipped[digest].tobytes()
    assert not data.exists()  # nothing cached for them


@pytest.mark.integration
def test_a_simulated_run_of_a_preset_optimises_nothing(data, monkeypatch, tmp_path, capsys):
    """The run service's preset path (app.procedure.run.request_plan) and the simulator."""

    def refuse(*_args, **_kwargs):
        raise AssertionError("optimised although the phases are shipped")

    monkeypatch.setattr(crestfactor, "optimise_phases", refuse)
    out = tmp_path / "runs"
    code = main(["run", "--sim", "--dut", "piezo", "--periods", "3", "--out", str(out)])
    assert code == 0, capsys.readouterr()
    assert not (data / "phases").exists()


def test_the_regeneration_tool_writes_files_the_store_trusts(tmp_path, monkeypatch):
    small = {"tiny": PhaseKey.of(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N, 0)}
    monkeypatch.setattr(phase_store, "preset_keys", lambda: small)
    (path,) = phase_store.write_shipped(tmp_path)
    assert path == tmp_path / "tiny.json"
    stored = phase_store.trusted(json.loads(path.read_text()), small["tiny"])
    assert stored.tobytes() == _real().tobytes()


def test_the_check_tool_fails_on_a_stale_file_and_passes_on_a_fresh_one(tmp_path, monkeypatch):
    small = {"tiny": PhaseKey.of(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N, 0)}
    monkeypatch.setattr(phase_store, "preset_keys", lambda: small)
    monkeypatch.setattr(phase_store, "shipped_folder", lambda: tmp_path)
    assert phase_store.main(["--check"]) == 1  # no file yet
    phase_store.main(["--write"])
    assert phase_store.main(["--check"]) == 0
    document = json.loads((tmp_path / "tiny.json").read_text())
    document["seed"] = 1  # written for another plan
    (tmp_path / "tiny.json").write_text(json.dumps(document))
    assert phase_store.main(["--check"]) == 1


# --- a custom plan's phases in the data directory -----------------------------------------


def test_a_custom_plan_is_optimised_once_then_read_from_the_data_directory(data, optimiser_calls):
    first = stored_phases(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N)
    assert len(optimiser_calls) == 1
    path = _cache_file(data)
    assert path.name == PhaseKey.of(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N, 0).digest + ".json"
    again = stored_phases(CUSTOM_BINS, 4.0 * CUSTOM_AMPS, CUSTOM_N)  # another level
    assert len(optimiser_calls) == 1  # read, not optimised
    assert first.tobytes() == again.tobytes() == _real().tobytes()
    other_seed = stored_phases(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N, seed=1)
    assert len(optimiser_calls) == 2 and other_seed.tobytes() == _real(seed=1).tobytes()
    assert len(list((data / "phases").iterdir())) == 2


def test_a_custom_plan_from_the_cli_is_cached_by_the_product(data, optimiser_calls, capsys):
    args = ["plan", "--frequencies", "20,50,160,315", "--sample-rate", "2000", "--json"]
    assert main(args) == 0
    first = json.loads(capsys.readouterr().out)
    assert len(optimiser_calls) == 1 and len(list((data / "phases").iterdir())) == 1
    assert main(args) == 0
    second = json.loads(capsys.readouterr().out)
    assert len(optimiser_calls) == 1
    assert [line["phase_rad"] for line in first["lines"]] == [
        line["phase_rad"] for line in second["lines"]
    ]


@pytest.mark.parametrize(
    "change",
    [
        {"bins": [3, 5, 8, 13, 22]},
        {"amplitudes": [1.0, 0.8, 0.5, 0.3, 0.25]},
        {"period": 130},
        {"seed": 7},
    ],
    ids=["bins", "amplitude-ratio", "period", "seed"],
)
def test_the_key_covers_everything_the_optimisation_depends_on(change):
    base = PhaseKey.of(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N, 0)
    other = PhaseKey.of(
        change.get("bins", CUSTOM_BINS),
        change.get("amplitudes", CUSTOM_AMPS),
        change.get("period", CUSTOM_N),
        change.get("seed", 0),
    )
    assert other.digest != base.digest


def test_the_key_names_the_algorithm_version(monkeypatch):
    before = PhaseKey.of(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N, 0)
    # the level aside (a factor that scales exactly: the key holds the optimiser's exact input)
    assert before == PhaseKey.of(CUSTOM_BINS, 4 * CUSTOM_AMPS, CUSTOM_N, 0)
    monkeypatch.setattr(crestfactor, "ALGORITHM_VERSION", crestfactor.ALGORITHM_VERSION + 1)
    after = PhaseKey.of(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N, 0)
    assert after.digest != before.digest


def _corrupt(path: Path, how: str) -> None:
    text = path.read_text()
    document = json.loads(text)
    if how == "not-json":
        path.write_text("{ this is not json")
    elif how == "truncated":
        path.write_text(text[: len(text) // 2])
    elif how == "binary":
        path.write_bytes(b"\xff\xfe\x00garbage")
    elif how == "another-format":
        path.write_text(json.dumps({"phases_rad": document["phases_rad"]}))
    elif how == "nan":
        path.write_text(text.replace(str(document["phases_rad"][2]), "NaN", 1))
    elif how == "too-few":
        document["phases_rad"] = document["phases_rad"][:-1]
        path.write_text(json.dumps(document))
    elif how == "out-of-range":
        document["phases_rad"][0] += 7.0
        path.write_text(json.dumps(document))
    elif how == "edited-value":
        document["phases_rad"][1] = (document["phases_rad"][1] + 1e-9) % 6.28
        path.write_text(json.dumps(document))
    elif how == "other-inputs":
        document["period_samples"] += 2  # key left as it was
        path.write_text(json.dumps(document))
    elif how == "old-algorithm":
        document["algorithm_version"] -= 1
        path.write_text(json.dumps(document))
    elif how == "peaks-aligned-with-checksum":  # self-consistent, worse than Schroeder's
        key = PhaseKey.of(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N, 0)
        aligned = np.full(CUSTOM_BINS.size, np.pi / 2)  # every sine at its peak at i = 0
        path.write_text(json.dumps(key.document(aligned)))
    else:
        raise AssertionError(how)


CORRUPTIONS = [
    "not-json",
    "truncated",
    "binary",
    "another-format",
    "nan",
    "too-few",
    "out-of-range",
    "edited-value",
    "other-inputs",
    "old-algorithm",
    "peaks-aligned-with-checksum",
]


@pytest.mark.parametrize("how", CORRUPTIONS)
def test_an_untrustworthy_cache_entry_is_ignored_recomputed_and_rewritten(
    data, custom_entry, optimiser_calls, caplog, how
):
    _with_entry(data, custom_entry)
    assert stored_phases(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N).tobytes() == _real().tobytes()
    assert not optimiser_calls  # the entry as written is trusted
    _corrupt(_cache_file(data), how)
    with caplog.at_level(logging.WARNING, logger="app.procedure.phase_store"):
        phases = stored_phases(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N)
    assert len(optimiser_calls) == 1  # computed again
    assert phases.tobytes() == _real().tobytes()
    assert "computing the phases again" in caplog.text
    again = stored_phases(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N)
    assert len(optimiser_calls) == 1 and again.tobytes() == phases.tobytes()  # rewritten


def test_another_plans_entry_under_this_plans_name_is_not_used(data, optimiser_calls):
    stored_phases(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N, seed=1)
    foreign = _cache_file(data)
    mine = phase_store.cache_path(PhaseKey.of(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N, 0))
    foreign.rename(mine)
    phases = stored_phases(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N)
    assert len(optimiser_calls) == 2 and phases.tobytes() == _real().tobytes()


def test_a_data_directory_that_cannot_be_written_costs_only_time(
    tmp_path, monkeypatch, optimiser_calls, caplog
):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    monkeypatch.setenv("ACCELCAL_DATA_DIR", str(blocker))  # its "phases" folder cannot exist
    with caplog.at_level(logging.WARNING, logger="app.procedure.phase_store"):
        phases = stored_phases(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N)
    assert phases.tobytes() == _real().tobytes()
    assert "not cached" in caplog.text


def test_invalid_lines_are_refused_by_the_optimiser_naming_them(data):
    with pytest.raises(ValueError, match="amplitude"):
        stored_phases(CUSTOM_BINS, np.array([1.0, 0.0, 1.0, 1.0, 1.0]), CUSTOM_N)
    with pytest.raises(ValueError, match="bin 5: appears more than once"):
        stored_phases(np.array([3, 5, 5]), np.ones(3), CUSTOM_N)
    stored_phases(CUSTOM_BINS, CUSTOM_AMPS, CUSTOM_N)  # now cached under bins 3, 5, 8, 13, 21
    with pytest.raises(ValueError, match=r"bin 5\.5: not an integer"):
        stored_phases(np.array([3, 5.5, 8, 13, 21]), CUSTOM_AMPS, CUSTOM_N)  # not bin 5's
    assert len(list((data / "phases").iterdir())) == 1
