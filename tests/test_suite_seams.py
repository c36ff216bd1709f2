"""The suite's own speed seams (tests/conftest.py) return what the real code returns."""

from __future__ import annotations

import numpy as np

import tests.conftest as suite
from dsp import crestfactor


def test_remembered_phase_optimisation_returns_the_real_phases_as_fresh_copies():
    bins, amplitudes = np.array([1, 2, 3, 5]), np.array([1.0, 0.5, 1.0, 2.0])
    assert crestfactor.optimise_phases is suite._memoised_optimise_phases
    assert suite._real_optimise_phases is not None
    real = suite._real_optimise_phases(bins, amplitudes, 64, seed=3)
    first = crestfactor.optimise_phases(bins, amplitudes, 64, seed=3)
    first[:] = -1.0  # a caller changing its phases changes nobody else's
    second = crestfactor.optimise_phases(bins, amplitudes, 64, seed=3)
    np.testing.assert_array_equal(second, real)
    other_seed = crestfactor.optimise_phases(bins, amplitudes, 64, seed=4)
    np.testing.assert_array_equal(
        other_seed, suite._real_optimise_phases(bins, amplitudes, 64, seed=4)
    )
    assert not np.array_equal(other_seed, real)  # the seed is part of the key


def test_the_dsp_tests_get_the_real_optimisation():
    assert suite._relative_is_real("dsp/test_crestfactor.py")
    assert not suite._relative_is_real("app/procedure/test_procedure.py")


def test_outside_the_dsp_tests_the_optimisation_runs_once_per_argument_set(monkeypatch):
    real, calls = suite._real_optimise_phases, []
    assert real is not None

    def counted(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(suite, "_real_optimise_phases", counted)
    bins, amplitudes = np.array([2, 3, 7]), np.ones(3)
    for _ in range(3):
        crestfactor.optimise_phases(bins, amplitudes, 32, seed=9)
    assert len(calls) == 1
