"""Every bench script runs to its end in its smoke mode (`--smoke`: a few seconds, figures not
meaningful), so none rots unseen (issue 27 point 4). A bench is code too."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCHES = sorted(p.name for p in (ROOT / "bench").glob("*.py"))
# each script's own smoke invocation (its docstring's "Smoke"/"--smoke" line); `--smoke` if absent
SMOKE_ARGS = {"impact.py": ["8", "2"]}  # RUNS WORKERS

pytestmark = pytest.mark.integration


def test_every_bench_script_is_listed():
    """A new bench script is picked up by the glob; the list is not empty by accident."""
    assert "import.py" in BENCHES and "gui_responsiveness.py" in BENCHES
    assert set(SMOKE_ARGS) <= set(BENCHES), "smoke arguments for a script that is gone"


@pytest.mark.long
@pytest.mark.parametrize("script", BENCHES)
def test_bench_runs_in_smoke_mode(script, tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT), QT_QPA_PLATFORM="offscreen")
    env["ACCELCAL_DATA_DIR"] = str(tmp_path / "data")  # no user data dir touched
    done = subprocess.run(
        [sys.executable, str(ROOT / "bench" / script), *SMOKE_ARGS.get(script, ["--smoke"])],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, f"{script} exited {done.returncode}:\n{done.stderr[-2000:]}"
    assert (done.stdout + done.stderr).strip(), f"{script} printed nothing"
