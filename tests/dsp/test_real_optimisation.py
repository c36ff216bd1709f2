"""The dsp tests run the real phase optimisation every call: the suite's memo of it
(tests/conftest.py) is for the runs and windows of the other tests only."""

from __future__ import annotations

import numpy as np

import tests.conftest as suite
from dsp import crestfactor


def test_every_call_in_a_dsp_test_runs_the_optimisation(monkeypatch):
    real, calls = suite._real_optimise_phases, []
    assert real is not None

    def counted(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(suite, "_real_optimise_phases", counted)
    bins, amplitudes = np.array([1, 2, 3]), np.ones(3)
    for _ in range(2):
        crestfactor.optimise_phases(bins, amplitudes, 32, seed=1)
    assert len(calls) == 2
