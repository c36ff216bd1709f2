"""Indexing run folders: verified folders only, by manifest hash, idempotent."""

from __future__ import annotations

import os
import shutil
import stat
from pathlib import Path

import pytest
from sqlalchemy import Engine, func, select
from sqlalchemy.orm import Session

from app.cli import main
from app.records.db.lab import Lab
from app.records.db.models import Run, Stand
from tests.records_db import seed_lab


@pytest.fixture(scope="module")
def runs_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two short simulated runs of SN-1, each a sealed folder (made in this process: the
    procedure writes the same folder as `accelcal run` does, without a fresh interpreter)."""
    from app.procedure.run import RunRequest, execute

    root = tmp_path_factory.mktemp("runs")
    for seed in (1, 2):
        request = RunRequest(
            dut="piezo", dut_id="SN-1", level_ms2=5.0, periods=4, seed=seed, out=root
        )
        assert execute(request).status == "complete"
    return root


def _writable_copy(source: Path, target: Path) -> Path:
    shutil.copytree(source, target)
    for path in [target, *target.iterdir()]:
        os.chmod(path, stat.S_IRWXU)
    return target


def test_import_indexes_verified_runs_once_and_lists_the_rest(
    engine: Engine, runs_root: Path, tmp_path: Path, qapp: object
) -> None:
    # qapp: the drift chart below is drawn with Qt in this process (tests/conftest.py collects
    # its garbage on the main thread)
    lab = seed_lab(Lab(engine, actor="t"), {"SN-1": "ACME Ltd"})
    root = tmp_path / "runs"
    for folder in sorted(runs_root.iterdir()):
        _writable_copy(folder, root / folder.name)
    tampered = _writable_copy(sorted(runs_root.iterdir())[0], tmp_path / "t" / "tampered")
    results = tampered / "results.json"
    results.write_text(results.read_text().replace('"complete"', '"complete" '))
    shutil.move(tampered, root / "zz-tampered")

    first = lab.import_runs(root)
    assert len(first.imported) == 2 and first.known == ()
    assert [(Path(f).name, why.split(":")[0]) for f, why in first.refused] == [
        ("zz-tampered", "modified")
    ]
    assert "hash mismatch" in first.refused[0][1]
    second = lab.import_runs(root)
    assert second.imported == () and sorted(second.known) == sorted(first.imported)
    with Session(engine) as s:
        assert s.scalar(select(func.count()).select_from(Run)) == 2
        assert s.scalar(select(func.count()).select_from(Stand)) == 1
    history = lab.history("SN-1")
    assert len(history.points) == 2
    assert all(p.reference_frequency_hz == 160.0 for p in history.points)
    for point in history.points:
        assert 0 < point.expanded_uncertainty_mv_per_ms2 < 0.05 * point.sensitivity_mv_per_ms2
    url = engine.url.render_as_string(hide_password=False)
    chart = tmp_path / "drift.png"
    assert main(["history", "SN-1", "--db", url, "--plot", str(chart)]) == 0
    assert chart.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and chart.stat().st_size > 5000
    assert main(["history", "SN-1", "--db", url, "--plot", str(chart)]) == 2  # never overwritten
    assert main(["db", "import", str(root), "--db", url]) == 0
