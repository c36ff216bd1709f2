"""The simulated stand without scipy.signal or scipy.linalg (issue 34): the tabulated
elliptic prototype, tf2ss and expm give scipy's floats (the tests may import scipy)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from sim import lti
from sim.models import PowerAmplifierModel, elliptic_zpk


@pytest.mark.parametrize("fs", [1000.0, 6000.0, 8000.0, 12800.0, 25600.0, 48000.0, 51200.0, 1234.5])
def test_tabulated_elliptic_design_is_scipys_bit_for_bit(fs: float) -> None:
    amp = PowerAmplifierModel()
    edge = amp.anti_imaging_edge * fs
    z, p, k = elliptic_zpk(
        amp.anti_imaging_order, edge, amp.anti_imaging_ripple_db, amp.anti_imaging_stop_db
    )
    z0, p0, k0 = scipy.signal.ellip(
        amp.anti_imaging_order,
        amp.anti_imaging_ripple_db,
        amp.anti_imaging_stop_db,
        2 * np.pi * edge,
        analog=True,
        output="zpk",
    )
    assert z.tobytes() == np.asarray(z0).tobytes()
    assert p.tobytes() == np.asarray(p0).tobytes()
    assert k == k0


def test_an_untabulated_elliptic_design_still_comes_from_scipy() -> None:
    z, p, k = elliptic_zpk(6, 1000.0, 0.5, 60.0)
    z0, p0, k0 = scipy.signal.ellip(6, 0.5, 60.0, 2 * np.pi * 1000.0, analog=True, output="zpk")
    assert np.array_equal(z, z0) and np.array_equal(p, p0) and k == k0


STAGES = [
    lti.resonance(150.0, 1.5),
    lti.highpass2(150.0, 1.5),
    lti.highpass1(0.2),
    lti.lowpass1(6000.0),
    (np.array([2.0, 3.0, 5.0]), np.array([4.0, 1.0, 7.0])),  # den[0] != 1: normalised
    (np.array([0.0, 1.0]), np.array([1.0, 2.0, 3.0])),  # a leading zero in the numerator
    (np.array([3.0]), np.array([2.0])),  # a gain
]


@pytest.mark.filterwarnings("ignore:Badly conditioned filter coefficients")
@pytest.mark.parametrize("stage", STAGES)
def test_tf2ss_is_scipys_bit_for_bit(stage) -> None:  # type: ignore[no-untyped-def]
    ours = lti.tf2ss(*stage)
    theirs = scipy.signal.tf2ss(*stage)
    for a, b in zip(ours, theirs, strict=True):
        assert a.shape == b.shape
        assert a.tobytes() == np.asarray(b, dtype=float).tobytes()


def test_tf2ss_refuses_an_improper_stage() -> None:
    with pytest.raises(ValueError, match="improper"):
        lti.tf2ss(np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0]))


def test_expm_is_scipys_to_rounding() -> None:
    """Over the norms of a ZOH block (A/fs with the poles below a few fs) and beyond."""
    rng = np.random.default_rng(34)
    for n in (1, 2, 5, 12, 40):
        for scale in (1e-6, 1e-2, 0.5, 3.0, 8.0):
            a = rng.standard_normal((n, n)) * scale / np.sqrt(n)
            expected = scipy.linalg.expm(a)
            assert np.max(np.abs(lti.expm(a) - expected)) <= 1e-12 * np.max(np.abs(expected))
    assert lti.expm(np.zeros((0, 0))).shape == (0, 0)


def test_the_sosfilt_kernel_is_loaded_without_the_scipy_signal_package() -> None:
    """In a fresh interpreter: the compiled kernel filters as scipy.signal.sosfilt does, and
    scipy/signal/__init__.py has not run until scipy.signal is imported, which then reuses it."""
    import subprocess
    import sys

    code = (
        "import sys, numpy as np\n"
        "from sim.lti import _sosfilt_kernel\n"
        "kernel = _sosfilt_kernel()\n"
        "assert kernel is not None\n"
        "assert 'scipy.signal' not in sys.modules, sorted(sys.modules)\n"
        "sos = np.array([[0.0, 1.0, 0.0, 1.0, -1.8, 0.9]])\n"
        "x = np.random.default_rng(1).standard_normal((1, 1000)); zi = np.zeros((1, 1, 2))\n"
        "y = x.copy(); kernel(sos, y, zi)\n"
        "import scipy.signal\n"
        "assert np.array_equal(y[0], scipy.signal.sosfilt(sos, x[0]))\n"
        "from scipy.signal._sosfilt import _sosfilt\n"
        "assert _sosfilt is kernel\n"
        "print('ok')\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"
