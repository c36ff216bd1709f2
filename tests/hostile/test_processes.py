"""Bad input that only a real process shows: a closed stdout pipe, a FIFO given as a file."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TIMEOUT_S = 60


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def _accelcal(*argv: str, **kwargs) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "app", *argv], cwd=ROOT, env=_env(), **kwargs)


@pytest.mark.parametrize("argv", [["plan", "--json"], ["simulate", "--list"]])
def test_output_into_a_closed_pipe_exits_141_quietly(argv):
    """`accelcal plan | head -1` where head has gone: exit 141 (SIGPIPE), no traceback."""
    process = _accelcal(*argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    process.stdout.close()  # the reader is gone before the first line is written
    try:
        _, err = process.communicate(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        process.kill()
        raise
    text = err.decode()
    assert process.returncode == 141, text
    assert "Traceback" not in text and "BrokenPipeError" not in text


@pytest.mark.parametrize(
    ("name", "argv"),
    [
        ("rec.csv", ["analyze", "{fifo}", "--preset", "piezo", "--reference-sensitivity", "1"]),
        ("stand.toml", ["run", "--stand", "{fifo}", "--out", "{out}"]),
        ("budget.toml", ["analyze", "x.csv", "--preset", "piezo", "--budget", "{fifo}"]),
    ],
)
def test_a_fifo_is_refused_at_once_never_read(tmp_path, name, argv):
    """Reading a FIFO with no writer blocks forever: it is refused from its metadata."""
    fifo = tmp_path / name
    os.mkfifo(fifo)
    argv = [a.replace("{fifo}", str(fifo)).replace("{out}", str(tmp_path / "runs")) for a in argv]
    if argv[0] == "analyze" and argv[1] == "x.csv":
        (tmp_path / "x.csv").write_text("1,2\n")
        argv[1] = str(tmp_path / "x.csv")
        argv += ["--reference-sensitivity", "1"]
    process = _accelcal(*argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        _, err = process.communicate(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        process.kill()
        process.communicate()
        pytest.fail(f"accelcal {argv[0]} blocked on the FIFO {fifo}")
    text = err.decode()
    assert process.returncode == 2, text
    assert f"{fifo}: is a FIFO (named pipe)" in text
    assert "Traceback" not in text
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        {name, *(["x.csv"] if argv[0] == "analyze" and "--budget" in argv else [])}
    )
