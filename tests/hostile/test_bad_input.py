"""Bad input, as a hostile or careless user types it: refused by name, exit 2, nothing written.

Each case is a command line (placeholders in braces are files made for the case, see INPUTS),
the text the refusal must contain (the option, field or file), and is run in-process through
`app.cli.main` with the working folder a fresh temporary one: exit 2, no traceback, and no file
created or changed anywhere in that folder. docs/reliability.md ("Bad input") lists them.
Inputs that would block or exhaust memory if a check regressed (FIFOs, /dev/zero) are tried in
real processes with a timeout and a memory limit instead (test_processes.py).
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest

from app.cli import main
from app.io.hdf5 import write_recording
from dsp.multisine import make_plan
from tests.synthetic import lowpass_response, make_recording

AI0, AI1, AI2 = ('physical = "sim/ai0"', 'physical = "sim/ai1"', 'physical = "sim/ai2"')
SIM_STAND = Path(__file__).resolve().parents[2] / "sim" / "stand.toml"


def _stand(tmp: Path, name: str, old: str, new: str) -> Path:
    text = SIM_STAND.read_text(encoding="utf-8")
    assert old in text, old
    path = tmp / name
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return path


def _int_recording(tmp: Path) -> Path:
    """A valid recording whose reference channel is then stored as integers."""
    plan = make_plan([10.0, 40.0, 160.0, 630.0], 6000, 12000, 5.0, 160.0)
    path = tmp / "int.h5"
    write_recording(path, make_recording(plan, lowpass_response(), periods=2))
    with h5py.File(path, "r+") as f:
        data = np.round(f["signals/reference"][()] * 1000).astype(np.int32)
        del f["signals/reference"]
        f.create_dataset("signals/reference", data=data)
    return path


def _folder(tmp: Path, name: str) -> Path:
    path = tmp / name
    path.mkdir()
    return path


def _plain(tmp: Path) -> Path:
    path = tmp / "plain.txt"
    path.write_text("not a folder\n")
    return path


INPUTS: dict[str, Callable[[Path], Path]] = {
    "plain": _plain,
    "int_h5": _int_recording,
    "dir_csv": lambda t: _folder(t, "folder.csv"),
    "dir_h5": lambda t: _folder(t, "folder.h5"),
    "dir_toml": lambda t: _folder(t, "folder.toml"),
    "typo_toml": lambda t: _stand(t, "typo.toml", "skew_s = 4e-6", "skew_seconds = 4e-6"),
    "lab_typo_toml": lambda t: _stand(t, "lab.toml", "address =", "adress ="),
    "section_typo_toml": lambda t: _stand(t, "sect.toml", "[dut_channel]", "[dut_chanel]"),
    "same_channel_toml": lambda t: _stand(t, "same.toml", AI1, AI0),
    "drive_channel_toml": lambda t: _stand(t, "drv.toml", AI2, AI1),
}

CSV_PLAN = ["--preset", "piezo", "--reference-sensitivity", "1"]
STEPPED = ["run", "--mode", "stepped-sine"]  # the run whose block --stepped-block sets

# (id, argv, text the refusal must contain)
CASES: list[tuple[str, list[str], str]] = [
    # numeric options: bounds, nan, inf (point 7)
    ("run-level-inf", ["run", "--level", "inf"], "--level: must be a finite number"),
    ("run-level-nan", ["run", "--level", "nan"], "--level: must be a finite number"),
    ("run-level-negative", ["run", "--level", "-5"], "--level: must be in (0, 1000] m/s^2"),
    ("run-level-zero", ["run", "--level", "0"], "--level: must be in (0, 1000]"),
    ("run-level-huge", ["run", "--level", "1e9"], "--level: must be in (0, 1000]"),
    ("run-level-text", ["run", "--level", "five"], "--level: 'five' is not a number"),
    ("run-level-unit-typo", ["run", "--level", "0.5gg"], "--level: '0.5gg' is not an accel"),
    ("run-level-wrong-unit", ["run", "--level", "5 kg"], "--level: '5 kg' is not an accel"),
    ("run-periods-1e12", ["run", "--periods", "1e12"], "--periods: must be in [1, 10000]"),
    (
        "run-periods-1",
        ["run", "--estimator", "periodic", "--periods", "1"],  # the lpm (default) takes 1
        "--periods: the periodic estimator needs at least 3 periods",
    ),
    ("run-periods-fraction", ["run", "--periods", "2.5"], "--periods: must be a whole number"),
    ("run-tolerance-negative", ["run", "--tolerance", "-1"], "--tolerance: must be in (0, 100] %"),
    ("run-tolerance-nan", ["run", "--tolerance", "nan"], "--tolerance: must be a finite number"),
    ("run-tolerance-over-100", ["run", "--tolerance", "101"], "--tolerance: must be in (0, 100]"),
    ("run-nominal-zero", ["run", "--nominal-sensitivity", "0"], "--nominal-sensitivity: must be"),
    ("run-nominal-negative", ["run", "--nominal-sensitivity", "-3"], "--nominal-sensitivity"),
    ("run-nominal-inf", ["run", "--nominal-sensitivity", "inf"], "--nominal-sensitivity"),
    ("run-seed-negative", ["run", "--seed", "-1"], "--seed: must be in [0, 4294967295]"),
    ("run-target-ua-inf", ["run", "--target-ua", "inf"], "--target-ua: must be a finite number"),
    ("run-target-ua-zero", ["run", "--target-ua", "0%"], "--target-ua: must be in (0, 100] %"),
    ("run-target-ua-150", ["run", "--target-ua", "150%"], "--target-ua: must be in (0, 100] %"),
    ("run-target-ua-150-bare", ["run", "--target-ua", "150"], "--target-ua: must be in (0, 100]"),
    ("run-max-time-nan", ["run", "--max-time", "nan"], "--max-time: must be a finite number"),
    ("run-max-time-48h", ["run", "--max-time", "48h"], "--max-time: must be in (0, 24 h]"),
    ("run-stepped-block-nan", [*STEPPED, "--stepped-block", "nan"], "--stepped-block: must be a"),
    ("run-stepped-block-0", [*STEPPED, "--stepped-block", "0"], "--stepped-block: must be in"),
    ("run-stepped-block-1min", [*STEPPED, "--stepped-block", "1min"], "must be in [0.01, 10] s"),
    ("run-stepped-block-multisine", ["run", "--stepped-block", "0.1"], "--stepped-block: the"),
    ("run-levels-empty-item", ["run", "--levels", "3,,5"], "--levels: '3,,5' has an empty item"),
    ("run-levels-inf", ["run", "--levels", "3,inf"], "--levels: 'inf': must be a finite"),
    ("run-levels-negative", ["run", "--levels", "3,-4"], "--levels: '-4': must be in (0, 1000]"),
    ("run-dut-unknown", ["run", "--dut", "nosuch"], "--dut: 'nosuch' is not in the DUT catalogue"),
    ("run-dut-typo", ["run", "--dut", "peizo"], "did you mean 'piezo'?"),
    ("run-out-under-a-file", ["run", "--out", "{plain}/runs"], "--out: "),
    ("run-out-unwritable", ["run", "--out", "/proc/accelcal-hostile"], "--out: "),
    ("gui-dut-unknown", ["gui", "--dut", "nosuch"], "--dut: 'nosuch' is not in the DUT catalogue"),
    ("gui-seed-nan", ["gui", "--seed", "nan"], "--seed: must be a finite number"),
    ("gui-out-unwritable", ["gui", "--out", "/proc/accelcal-hostile"], "--out: "),
    ("simulate-dut-unknown", ["simulate", "--dut", "nosuch"], "--dut: 'nosuch' is not in the"),
    (
        "simulate-periods-1e12",
        ["simulate", "--periods", "1e12"],
        "--periods: must be in [1, 10000]",
    ),
    ("simulate-settle-negative", ["simulate", "--settle", "-1"], "--settle: must be in [0, 1000]"),
    ("simulate-level-inf", ["simulate", "--level", "inf"], "--level: must be a finite number"),
    ("simulate-out-unwritable", ["simulate", "--out", "/proc/accelcal/rec.h5"], "--out: "),
    ("plan-frequencies-empty-item", ["plan", "--frequencies", "10,,20"], "--frequencies: item 2"),
    (
        "plan-frequencies-trailing-comma",
        ["plan", "--frequencies", "10,160,"],
        "--frequencies: item 3",
    ),
    ("plan-frequencies-nan", ["plan", "--frequencies", "10,nan,160"], "--frequencies: 'nan'"),
    ("plan-frequencies-negative", ["plan", "--frequencies", "-10,160"], "--frequencies: '-10'"),
    ("plan-sample-rate-inf", ["plan", "--sample-rate", "inf"], "--sample-rate: must be a finite"),
    ("plan-period-3", ["plan", "--period", "3"], "--period: must be in [4, 16777216] samples"),
    ("plan-period-huge", ["plan", "--period", "1e12"], "--period: must be in [4, 16777216]"),
    ("plan-mains-zero", ["plan", "--mains", "0"], "--mains: must be in [1, 1000] Hz"),
    ("plan-reference-negative", ["plan", "--reference-frequency", "-160"], "--reference-frequency"),
    ("analyze-settle-negative", ["analyze", "x.csv", "--settle-periods", "-1"], "--settle-periods"),
    (
        "analyze-coverage-1.5",
        ["analyze", "x.csv", "--coverage", "1.5"],
        "--coverage: must be in (0, 1)",
    ),
    ("analyze-coverage-nan", ["analyze", "x.csv", "--coverage", "nan"], "--coverage: must be a"),
    (
        "analyze-segments-0",
        ["analyze", "x.csv", "--segments", "0"],
        "--segments: must be in [1, 10000]",
    ),
    (
        "analyze-skew-1s",
        ["analyze", "x.csv", "--skew", "1"],
        "--skew: must be in [-0.001, 0.001] s",
    ),
    ("analyze-skew-too-negative", ["analyze", "x.csv", "--skew", "-2e-02"], "--skew: must be in"),
    ("analyze-range-nan", ["analyze", "x.csv", "--range", "nan"], "--range: must be a finite"),
    ("analyze-tolerance-nan", ["analyze", "x.csv", "--tolerance", "nan"], "--tolerance: must be a"),
    (
        "analyze-ref-sensitivity-0",
        ["analyze", "x.csv", "--reference-sensitivity", "0"],
        "--reference-sensitivity",
    ),
    (
        "analyze-dut-gain-negative",
        ["analyze", "x.csv", "--dut-gain", "-1"],
        "--dut-gain: must be in",
    ),
    ("analyze-csv-unwritable", ["analyze", "{plain}", "--csv", "/proc/accelcal/r.csv"], "--csv: "),
    # files (point 8)
    ("analyze-folder-csv", ["analyze", "{dir_csv}", *CSV_PLAN], "is a folder but not a run folder"),
    ("analyze-folder-h5", ["analyze", "{dir_h5}"], "is a folder but not a run folder"),
    ("analyze-int-dataset", ["analyze", "{int_h5}"], "/signals/reference: dataset of type int32"),
    (
        "analyze-budget-folder",
        ["analyze", "{plain}", *CSV_PLAN, "--budget", "{dir_toml}"],
        "--budget: ",
    ),
    ("stand-folder", ["run", "--stand", "{dir_toml}"], "is a folder"),
    (
        "stand-unknown-key",
        ["run", "--stand", "{typo_toml}"],
        "daq.skew_seconds: unknown key; did you mean 'skew_s'?",
    ),
    (
        "stand-unknown-lab-key",
        ["run", "--stand", "{lab_typo_toml}"],
        "laboratory.adress: unknown key; did you mean 'address'?",
    ),
    (
        "stand-unknown-section",
        ["run", "--stand", "{section_typo_toml}"],
        "dut_chanel: unknown key; did you mean 'dut_channel'?",
    ),
    (
        "stand-same-channel",
        ["run", "--stand", "{same_channel_toml}"],
        "daq.dut.physical: 'sim/ai0' is also daq.reference.physical",
    ),
    (
        "stand-drive-on-dut-channel",
        ["run", "--stand", "{drive_channel_toml}"],
        "daq.drive.physical: 'sim/ai1' is also daq.dut.physical",
    ),
]


def _snapshot(folder: Path) -> dict[str, tuple[int, float]]:
    """Every path under `folder` (links not followed) with its size and modification time."""
    out = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            path = Path(root, name)
            info = path.lstat()
            out[str(path.relative_to(folder))] = (info.st_size, info.st_mtime)
    return out


def _fill(argv: list[str], tmp: Path) -> list[str]:
    made: dict[str, str] = {}
    out = []
    for arg in argv:
        for key, factory in INPUTS.items():
            token = "{" + key + "}"
            if token in arg:
                if key not in made:
                    made[key] = str(factory(tmp))
                arg = arg.replace(token, made[key])
        out.append(arg)
    return out


@pytest.mark.parametrize(("argv", "message"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_is_refused_by_name_with_exit_2_and_nothing_written(
    tmp_path, monkeypatch, capsys, argv, message
):
    work = tmp_path / "work"
    work.mkdir()
    argv = _fill(argv, work)
    if argv[0] in ("run", "gui") and "--out" not in argv:
        argv += ["--out", str(work / "runs")]
    if argv[0] == "simulate" and "--out" not in argv:
        argv += ["--out", str(work / "rec.h5")]
    monkeypatch.chdir(work)
    before = _snapshot(work)
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert message in err
    assert "Traceback" not in err
    assert _snapshot(work) == before


def test_the_table_covers_every_point_7_and_8_item_of_issue_12():
    ids = {c[0] for c in CASES}
    assert len(CASES) >= 60
    for needed in (
        "run-level-inf",
        "run-level-nan",
        "run-periods-1e12",
        "analyze-settle-negative",
        "run-tolerance-negative",
        "run-tolerance-nan",
        "run-tolerance-over-100",
        "run-out-unwritable",
        "run-nominal-zero",
        "gui-dut-unknown",
        "analyze-int-dataset",
        "stand-unknown-key",
        "stand-same-channel",
        "plan-frequencies-empty-item",
    ):
        assert needed in ids


# --- certificate fields (point 9) -----------------------------------------------------------

CERTIFICATE_OK = [
    "--customer",
    "ACME Ltd",
    "--customer-address",
    "1 Test Street, 00-001 Testtown",
    "--authorised-by",
    "J. Smith",
    "--temperature",
    "23",
    "--mounting",
    "stud",
]

CERTIFICATE_CASES: list[tuple[str, dict[str, str], str]] = [
    ("blank-customer", {"--customer": "   "}, "customer (--customer)"),
    ("empty-customer", {"--customer": ""}, "customer (--customer)"),
    ("blank-authorised-by", {"--authorised-by": " \t"}, "authorised_by (--authorised-by)"),
    ("temperature-nan", {"--temperature": "nan"}, "--temperature: must be a finite number"),
    ("temperature-minus-300", {"--temperature": "-300"}, "--temperature: must be in [-50, 150]"),
    ("temperature-inf", {"--temperature": "inf"}, "--temperature: must be a finite number"),
    ("issue-date-banana", {"--issue-date": "banana"}, "issue_date (--issue-date): 'banana'"),
    ("issue-date-30-feb", {"--issue-date": "2026-02-30"}, "issue_date (--issue-date)"),
    ("issue-date-us-order", {"--issue-date": "11/23/2026"}, "issue_date (--issue-date)"),
    ("issue-date-compact", {"--issue-date": "20261123"}, "issue_date (--issue-date)"),
]


@pytest.mark.parametrize(
    ("change", "message"), [c[1:] for c in CERTIFICATE_CASES], ids=[c[0] for c in CERTIFICATE_CASES]
)
def test_bad_certificate_fields_are_refused_by_name(
    complete_run, tmp_path, capsys, change, message
):
    argv = list(CERTIFICATE_OK)
    for option, value in change.items():
        if option in argv:
            argv[argv.index(option) + 1] = value
        else:
            argv += [option, value]
    root = complete_run.parent
    before = _snapshot(root)
    code = main(["certificate", str(complete_run), *argv, "--out", str(tmp_path / "c.pdf")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert message in err
    assert "Traceback" not in err
    assert _snapshot(root) == before and not (tmp_path / "c.pdf").exists()


def test_a_certificate_number_is_never_reused(complete_run, tmp_path, capsys):
    run = tmp_path / "runs" / complete_run.name  # a register of its own, not the session's
    shutil.copytree(complete_run, run)
    argv = ["certificate", str(run), *CERTIFICATE_OK, "--certificate-number", "H-1"]
    assert main([*argv, "--out", str(tmp_path / "a.pdf")]) == 0
    capsys.readouterr()
    assert main([*argv, "--out", str(tmp_path / "b.pdf")]) == 2
    err = capsys.readouterr().err
    assert "--certificate-number: H-1 is already used" in err and "Traceback" not in err
    assert not (tmp_path / "b.pdf").exists()
