"""Bad input that only a real process shows, or that would hang or exhaust the test process if
a check regressed: a closed stdout pipe, a FIFO or /dev/zero given as a file. Each runs with a
timeout and an address-space limit."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TIMEOUT_S = 60
MEMORY_LIMIT = 1536 << 20  # bytes of address space: ample for accelcal, not for /dev/zero


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def _accelcal(*argv: str, **kwargs) -> subprocess.Popen:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.Popen(
        [sys.executable, "-m", "app", *argv],
        cwd=ROOT,
        env=env,
        preexec_fn=_limit_memory,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        **kwargs,
    )


def _finish(process: subprocess.Popen, what: str) -> str:
    try:
        _, err = process.communicate(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        process.kill()
        process.communicate()
        pytest.fail(f"accelcal {what}: still running after {TIMEOUT_S} s")
    return err.decode()


@pytest.mark.parametrize("argv", [["plan", "--json"], ["simulate", "--list"]])
def test_output_into_a_closed_pipe_exits_141_quietly(argv):
    """`accelcal plan | head -1` where head has gone: exit 141 (SIGPIPE), no traceback."""
    process = _accelcal(*argv)
    process.stdout.close()  # the reader is gone before the first line is written
    text = _finish(process, " ".join(argv))
    assert process.returncode == 141, text
    assert "Traceback" not in text and "BrokenPipeError" not in text


CSV = ["--preset", "piezo", "--reference-sensitivity", "1"]


@pytest.mark.parametrize(
    ("name", "kind", "argv", "message"),
    [
        ("rec.csv", "fifo", ["analyze", "{input}", *CSV], "is a FIFO (named pipe)"),
        ("stand.toml", "fifo", ["run", "--stand", "{input}"], "is a FIFO (named pipe)"),
        (
            "b.toml",
            "fifo",
            ["analyze", "{csv}", *CSV, "--budget", "{input}"],
            "is a FIFO (named pipe)",
        ),
        ("zero.csv", "zero", ["analyze", "{input}", *CSV], "is a character device"),
        ("zero.h5", "zero", ["analyze", "{input}"], "is a character device"),
        ("zero.toml", "zero", ["run", "--stand", "{input}"], "is a character device"),
        (
            "b.toml",
            "zero",
            ["analyze", "{csv}", *CSV, "--budget", "{input}"],
            "is a character device",
        ),
    ],
)
def test_a_fifo_or_device_is_refused_at_once_never_read(tmp_path, name, kind, argv, message):
    """Reading a FIFO with no writer blocks forever and /dev/zero never ends: both are refused
    from their metadata, before anything is opened."""
    path = tmp_path / name
    if kind == "fifo":
        os.mkfifo(path)
    else:
        path.symlink_to("/dev/zero")
    csv = tmp_path / "x.csv"
    csv.write_text("1,2\n")
    argv = [a.replace("{input}", str(path)).replace("{csv}", str(csv)) for a in argv]
    if argv[0] == "run":
        argv += ["--out", str(tmp_path / "runs")]
    before = sorted(p.name for p in tmp_path.iterdir())
    process = _accelcal(*argv)
    text = _finish(process, " ".join(argv))
    assert process.returncode == 2, text
    assert f"{path}: {message}" in text
    assert "Traceback" not in text
    assert sorted(p.name for p in tmp_path.iterdir()) == before
