"""`accelcal run --periods` below the estimator's minimum is refused (issue 13 point 5)."""

from __future__ import annotations

import pytest

from app.cli import main


@pytest.mark.parametrize(
    ("periods", "estimator", "need"), [("2", "periodic", 3), ("2", "h1", 3), ("3", "seed", 4)]
)
def test_run_with_too_few_periods_exits_2_naming_periods(
    capsys, tmp_path, periods, estimator, need
):
    code = main(
        ["run", "--sim", "--periods", periods, "--estimator", estimator, "--out", str(tmp_path)]
    )
    err = capsys.readouterr().err
    assert code == 2
    assert "--periods" in err and f"needs at least {need} periods" in err, err
    assert not any(tmp_path.iterdir())  # refused before anything ran or was stored
