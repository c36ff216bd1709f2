"""The command line starts light: `import app.cli` imports no GUI, hardware, file-format or
database library, no numpy and no scipy; a records command imports no numpy, scipy or Alembic;
a warm simulated run imports none of scipy.signal, scipy.stats, scipy.special, scipy.linalg,
pint or SQLAlchemy (issue 14 point 4, issue 34 point 3; timing in bench/startup.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
HEAVY = (
    "PySide6",
    "pyqtgraph",
    "h5py",
    "reportlab",
    "nidaqmx",
    "pyvisa",
    "pyvisa_sim",
    "sqlalchemy",
    "alembic",
    "psycopg",
    "scipy",
    "pint",
)
NUMERIC = ("numpy", "scipy")
# what a warm LPM run on the simulated stand has no use for (the full names: scipy.signal's
# compiled sosfilt kernel is loaded on its own, as scipy.signal._sosfilt)
NOT_IN_A_RUN = (
    "scipy.signal",
    "scipy.stats",
    "scipy.special",
    "scipy.linalg",
    "scipy.interpolate",
    "scipy.optimize",
    "pint",
    "sqlalchemy",
    "alembic",
    "numpy.ma",  # np.unique and np.median import it (about 40 ms): sorted and dsp.quantiles
)

pytestmark = pytest.mark.integration  # a fresh interpreter per test


def modules_after(code: str, env: dict[str, str] | None = None) -> set[str]:
    """Every module name in sys.modules after `code` ran in a fresh interpreter."""
    probe = f"{code}\nimport sys, json\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run(
        [sys.executable, "-c", probe],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
        env=env,
    )
    return set(json.loads(out.stdout.strip().splitlines()[-1]))


def imported_by(code: str, packages: tuple[str, ...] = HEAVY, env: dict[str, str] | None = None):  # type: ignore[no-untyped-def]
    """Top-level packages of `packages` that `code`, run in a fresh interpreter, imports."""
    return sorted({m.split(".")[0] for m in modules_after(code, env)} & set(packages))


def data_env(tmp_path: Path) -> dict[str, str]:
    """The environment with a data directory of its own (stored responses, records)."""
    env = dict(os.environ, ACCELCAL_DATA_DIR=str(tmp_path / "data"))
    env.pop("ACCELCAL_DB", None)
    return env


def test_import_app_cli_imports_no_heavy_library_and_no_numpy() -> None:
    assert imported_by("import app.cli", HEAVY + NUMERIC) == []


def test_help_and_parsing_import_no_heavy_library() -> None:
    code = (
        "import contextlib, io\nfrom app import cli\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    cli.main(['--help'])\n"
        "    cli.build_parser().parse_args(['run', '--sim', '--dut', 'capacitive', '--level', '3'])"
    )
    assert imported_by(code) == []


def test_plan_of_a_preset_imports_no_scipy_nor_pint() -> None:
    code = (
        "import contextlib, io\nfrom app import cli\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    assert cli.main(['plan', '--preset', 'piezo']) == 0"
    )
    assert imported_by(code) == []


def test_records_commands_import_no_numpy_scipy_or_alembic(tmp_path: Path) -> None:
    env = data_env(tmp_path)
    url = f"sqlite:///{tmp_path / 'records.sqlite'}"
    subprocess.run(
        [sys.executable, "-m", "app", "db", "upgrade", "--db", url],
        cwd=ROOT,
        env=env,
        check=True,
        capture_output=True,
    )
    for command in (["customers", "list"], ["sensors", "list"], ["due"], ["customers", "--help"]):
        code = (
            "import contextlib, io\nfrom app import cli\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            f"    assert cli.main({[*command, '--db', url]!r}) == 0"
        )
        if command[-1] == "--help":
            code = code.replace(f", '--db', {url!r}", "")
        found = imported_by(code, (*NUMERIC, "alembic", "pint", "h5py", "PySide6"), env)
        assert found == [], command


def test_a_records_command_is_parsed_as_the_full_parser_does() -> None:
    """The records-only parse (app.cli._parse) gives the namespace the full parser gives, for
    every records command named in app.cli.records.COMMAND_NAMES."""
    import argparse

    from app.cli import _parse
    from app.cli.parser import build_parser
    from app.cli.records import COMMAND_NAMES, add_commands

    sub = argparse.ArgumentParser().add_subparsers()
    assert set(add_commands(sub)) == COMMAND_NAMES

    for words in (
        ["customers", "list", "--json"],
        ["--verbose", "due", "--days", "30"],
        ["sensors", "list", "--db", "sqlite:///x.sqlite"],
    ):
        args, handler = _parse(words)
        assert handler is not None
        full = vars(build_parser().parse_args(words))
        assert vars(args) == full


def test_a_warm_simulated_run_imports_no_scipy_signal_stats_special_pint_or_sqlalchemy(
    tmp_path: Path,
) -> None:
    env = data_env(tmp_path)
    run = ["run", "--sim", "--dut", "piezo", "--target-ua", "0.2%", "--estimator", "lpm"]
    run += ["--out", str(tmp_path / "runs")]
    subprocess.run(  # cold: measures and stores the stand's response
        [sys.executable, "-m", "app", *run], cwd=ROOT, env=env, check=True, capture_output=True
    )
    code = (
        "import contextlib, io\nfrom app import cli\n"
        "quiet = contextlib.redirect_stdout(io.StringIO())\n"
        "with quiet, contextlib.redirect_stderr(io.StringIO()):\n"
        f"    assert cli.main({run!r}) == 0"
    )
    modules = modules_after(code, env)
    assert "numpy" in modules and "scipy.signal._sosfilt" in modules  # it did simulate
    assert sorted(name for name in NOT_IN_A_RUN if name in modules) == []


def test_a_command_still_gets_its_errors_caught_by_kind(tmp_path: Path) -> None:
    """The errors of lazily imported modules map to their exit codes (2: bad input)."""
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not an HDF5 file")
    done = subprocess.run(
        [sys.executable, "-m", "app", "analyze", str(bad)], cwd=ROOT, capture_output=True, text=True
    )
    assert done.returncode == 2, done.stderr
    assert "error:" in done.stderr


# what `accelcal plan --preset piezo` had no use for and imported until issue 34 point 3's
# second pass (bench/startup.py: 2.76x `import numpy` before, under 2x after): the run's
# options table and the simulated stand's models (through the full parser), the records
# commands (the parse's first step), the stand file's full reader (for its travel alone) and
# the LPM (for a preset's period, which needs no grid design)
NOT_IN_A_PLAN = (
    "app.cli.parser",
    "app.cli.records",
    "app.procedure.options",
    "app.stand.simulated",
    "app.stand.config",
    "app.records",
    "sim.models",
    "dsp.lpm",
    "dsp.calibration",
    "dsp.uncertainty",
    "hardware.interfaces",
)


def test_plan_of_a_preset_imports_neither_the_run_options_the_stand_nor_the_records() -> None:
    code = (
        "import contextlib, io\nfrom app import cli\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    assert cli.main(['plan', '--preset', 'piezo']) == 0"
    )
    modules = modules_after(code)
    assert "app.cli.plan" in modules and "dsp.multisine" in modules  # it did plan
    assert sorted(name for name in NOT_IN_A_PLAN if name in modules) == []


def test_a_plan_command_is_parsed_as_the_full_parser_does() -> None:
    """The plan-only parse (app.cli._parse) gives the namespace the full parser gives, and
    refuses what it refuses (an exciter the simulated stand has not: exit 2)."""
    import contextlib
    import io

    from app.cli import _parse
    from app.cli.parser import build_parser

    for words in (
        ["plan", "--preset", "piezo"],
        ["plan", "--json", "--frequencies", "10,...,160", "--level", "0.5g", "--mains", "60"],
        ["--verbose", "plan", "--exciter", "long-stroke", "--profile", "velocity", "--corner", "5"],
    ):
        args, handler = _parse(words)
        assert handler is None
        assert vars(args) == vars(build_parser().parse_args(words))
    with contextlib.redirect_stderr(io.StringIO()) as said, pytest.raises(SystemExit) as exited:
        _parse(["plan", "--exciter", "no-such-exciter"])
    assert exited.value.code == 2
    assert "'long-stroke'" in said.getvalue()  # the choices listed, looked up when needed


def test_the_plans_travel_is_the_built_in_stands() -> None:
    """`plan` reads the built-in stand's travel from its file alone (not app.stand.config)."""
    from app.cli.plan import builtin_stroke_m
    from app.stand.config import load

    assert builtin_stroke_m() == load().limits.displacement_peak_to_peak_m


def test_a_preset_plan_checks_only_its_own_shipped_phases() -> None:
    """Each check of a shipped file synthesises its plan twice (app.procedure.phase_store
    .trusted): a plan checks the one file it uses, once per process, not every preset's."""
    code = (
        "from app.procedure import phase_store\n"
        "from app.procedure.planning import PlanRequest, build_plan\n"
        "checked = []\nreal = phase_store.trusted\n"
        "def counted(document, key):\n"
        "    checked.append(key.digest)\n"
        "    return real(document, key)\n"
        "phase_store.trusted = counted\n"
        "for level in (1.0, 2.0):\n"
        "    build_plan(PlanRequest(preset='piezo', level_ms2=level))\n"
        "assert checked == [phase_store.preset_keys()['piezo'].digest], checked\n"
    )
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True, capture_output=True)


def test_a_plans_oversampled_figures_are_synthesised_once() -> None:
    """`accelcal plan` asked for the predicted peaks twice (the stroke check, the report) and
    the continuous crest factor once: three syntheses each time; a plan is immutable, so they
    are made once per plan, and give what a fresh plan gives."""
    from unittest import mock

    from app.procedure.phase_store import stored_phases
    from dsp import crestfactor
    from dsp.multisine import preset_plan

    plan = preset_plan("piezo", level_ms2=3.0, optimiser=stored_phases)
    with mock.patch.object(crestfactor, "synthesize", wraps=crestfactor.synthesize) as synth:
        first = plan.predicted_peaks()
        crest = plan.continuous_crest_factor()
        assert plan.predicted_peaks() == first
        assert synth.call_count == 3  # acceleration, velocity, displacement: once
    fresh = preset_plan("piezo", level_ms2=3.0, optimiser=stored_phases)
    assert fresh.continuous_crest_factor() == crest and fresh.predicted_peaks() == first
    assert plan.with_amplitudes(6.0).predicted_peaks().acceleration_ms2 == pytest.approx(
        2 * first.acceleration_ms2, rel=1e-12
    )  # another plan: its own figures
