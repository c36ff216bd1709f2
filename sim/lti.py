"""Exact discrete-time equivalents of continuous LTI models driven by a zero-order hold.

The DAQ's analog output holds each sample for one sample period, so discretising a continuous
model (A, B, C, D) with a ZOH is exact at the sample instants, resonances above Nyquist
included (they alias, as they do on a board without anti-alias filter). An output sampled
`delay_s` after the input sample instant (multiplexed ADC) is exact too:
x(t_k + tau) = e^{A tau} x_k + Gamma(tau) B u_k, with Gamma(tau) = int_0^tau e^{A s} ds.

Models are built as a series of low-order stages (well conditioned, no high-order
polynomials) and run in modal form: each discrete pole (or conjugate pair) is one real
second-order section filtered by `scipy.signal.sosfilt` with carried state, so cutting a
signal into blocks of any size gives the same output.
"""

from __future__ import annotations

import functools
import importlib.machinery
import importlib.util
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# Neither scipy.signal nor scipy.linalg is imported on a run's path: scipy.signal costs about
# 1.5 s (it imports scipy.stats, interpolate, optimize), scipy.linalg twice `import numpy`,
# against a warm run's whole budget of 1.5 s (issue 34). `tf2ss` below is scipy's,
# transcribed; `expm` Higham's scaling and squaring; the sections are filtered by the compiled
# kernel behind scipy.signal.sosfilt, loaded on its own.

Stage = tuple[np.ndarray, np.ndarray]  # (num, den) polynomials in s, highest power first
_MIX_CHUNK = 2048  # samples per matrix product when mixing the sections into the outputs


def resonance(frequency_hz: float, q: float) -> Stage:
    """Unity-DC-gain second-order low-pass w0^2 / (s^2 + w0/Q s + w0^2)."""
    w0 = 2 * np.pi * frequency_hz
    return np.array([w0**2]), np.array([1.0, w0 / q, w0**2])


def highpass2(frequency_hz: float, q: float) -> Stage:
    """Second-order high-pass s^2 / (s^2 + w0/Q s + w0^2) (unity gain above w0)."""
    w0 = 2 * np.pi * frequency_hz
    return np.array([1.0, 0.0, 0.0]), np.array([1.0, w0 / q, w0**2])


def highpass1(frequency_hz: float) -> Stage:
    """First-order high-pass s / (s + wc)."""
    wc = 2 * np.pi * frequency_hz
    return np.array([1.0, 0.0]), np.array([1.0, wc])


def lowpass1(frequency_hz: float) -> Stage:
    """First-order low-pass wc / (s + wc)."""
    wc = 2 * np.pi * frequency_hz
    return np.array([wc]), np.array([1.0, wc])


@dataclass(frozen=True)
class Model:
    """A continuous SISO model: a gain times a series of stages."""

    stages: tuple[Stage, ...]
    gain: float = 1.0

    def then(self, *stages: Stage, gain: float = 1.0) -> Model:
        """This model followed by more stages and a gain."""
        return Model(self.stages + tuple(stages), self.gain * gain)

    def response(self, frequency_hz: np.ndarray) -> np.ndarray:
        """Complex frequency response at frequencies in Hz (continuous, no ZOH, no delay)."""
        s = 2j * np.pi * np.asarray(frequency_hz, dtype=float)
        out = np.full(s.shape, self.gain, dtype=complex)
        for num, den in self.stages:
            out *= np.polyval(num, s) / np.polyval(den, s)
        return out

    def state_space(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(A, B, C, D) of the series connection."""
        a = np.zeros((0, 0))
        b = np.zeros((0, 1))
        c = np.zeros((1, 0))
        d = np.array([[self.gain]])
        for num, den in self.stages:
            a2, b2, c2, d2 = tf2ss(num, den)
            n1, n2 = a.shape[0], a2.shape[0]
            a_new = np.zeros((n1 + n2, n1 + n2))
            a_new[:n1, :n1] = a
            a_new[n1:, :n1] = b2 @ c
            a_new[n1:, n1:] = a2
            b = np.vstack([b, b2 @ d])
            c = np.hstack([d2 @ c, c2])
            d = d2 @ d
            a = a_new
        return a, b, c, d


def tf2ss(
    num: np.ndarray, den: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(A, B, C, D) of one stage in controller canonical form: scipy.signal.tf2ss for a 1-D
    numerator, operation for operation (the same floats: tests/sim/test_lti_exact.py), without
    importing scipy.signal."""
    den = np.atleast_1d(np.asarray(den))
    num = np.atleast_1d(np.asarray(num))
    if den.ndim != 1 or num.ndim != 1:
        raise ValueError("tf2ss: numerator and denominator must be 1-D polynomials")
    if np.all(den == 0):
        raise ValueError("tf2ss: the denominator is zero")
    den = den[np.argmax(den != 0) :]  # leading zeros trimmed, as scipy's normalize does
    num2, den = num[None, :] / den[0], den / den[0]
    leading = 0
    while leading < num2.shape[1] - 1 and np.all(np.abs(num2[:, leading]) <= 1e-14):
        leading += 1  # scipy warns (BadCoefficients) and trims these too
    num2 = num2[:, leading:]
    m, k = num2.shape[1], len(den)
    if m > k:
        raise ValueError("tf2ss: improper transfer function (numerator longer than denominator)")
    num2 = np.hstack((np.zeros((1, k - m), dtype=num2.dtype), num2))
    d = np.atleast_2d(num2[:, 0])
    if k == 1:
        return np.zeros((1, 1)), np.zeros((1, 1)), np.zeros((1, 1)), d.reshape((1, 1))
    a = np.r_[-np.array([den[1:]]), np.eye(k - 2, k - 1)]
    b = np.eye(k - 1, 1)
    c = num2[:, 1:] - np.outer(num2[:, 0], den[1:])
    return a, b, c, d.reshape((1, 1))


_KERNEL_MODULE = "scipy.signal._sosfilt"


@functools.cache
def _sosfilt_kernel() -> Callable[[np.ndarray, np.ndarray, np.ndarray], None] | None:
    """The compiled kernel behind scipy.signal.sosfilt (in place, without its copies), or None
    on a scipy that lays it out otherwise.

    Its extension module is loaded from scipy's folder under its own name, without running
    scipy/signal/__init__.py (which imports scipy.stats and more: about 1.5 s); it is entered
    in sys.modules, so a later `import scipy.signal` finds and reuses it."""
    loaded: object | None = sys.modules.get(_KERNEL_MODULE)
    if loaded is None:
        loaded = _load_kernel_module()
    kernel = getattr(loaded, "_sosfilt", None) if loaded is not None else None
    return kernel if callable(kernel) else None


def _load_kernel_module() -> object | None:
    """scipy's _sosfilt extension, loaded by file (None: not where this scipy version puts it)."""
    scipy_spec = importlib.util.find_spec("scipy")
    folders = scipy_spec.submodule_search_locations if scipy_spec is not None else None
    if not folders:  # pragma: no cover - no scipy
        return None
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        path = Path(folders[0]) / "signal" / f"_sosfilt{suffix}"
        if path.is_file():
            break
    else:  # pragma: no cover - another scipy layout
        return None
    loader = importlib.machinery.ExtensionFileLoader(_KERNEL_MODULE, str(path))
    spec = importlib.util.spec_from_file_location(_KERNEL_MODULE, path, loader=loader)
    if spec is None:  # pragma: no cover
        return None
    module = importlib.util.module_from_spec(spec)
    sys.modules[_KERNEL_MODULE] = module  # one instance: the extension cannot be loaded twice
    try:
        loader.exec_module(module)
    except ImportError:  # pragma: no cover - another scipy layout
        del sys.modules[_KERNEL_MODULE]
        return None
    return module


def _sosfilt_inplace(sos: np.ndarray, x: np.ndarray, zi: np.ndarray) -> None:
    """Filter the rows of C-contiguous `x` (rows, n) through `sos` in place; `zi`
    (rows, sections, 2) carries the state in place."""
    kernel = _sosfilt_kernel()
    if kernel is not None:
        kernel(sos, x, zi)
        return
    import scipy.signal  # pragma: no cover - another scipy layout: the public function

    for r in range(x.shape[0]):  # pragma: no cover
        x[r], zi[r] = scipy.signal.sosfilt(sos, x[r], zi=zi[r])


# Higham (2005), "The scaling and squaring method for the matrix exponential revisited":
# the largest 1-norm for which each diagonal Pade approximant is exact to double precision,
# and the coefficients of the degree-13 one
_PADE_THETA = (
    (3, 1.495585217958292e-2),
    (5, 2.539398330063230e-1),
    (7, 9.504178996162932e-1),
    (9, 2.097847961257068e0),
)
_THETA_13 = 5.371920351148152
_PADE_13 = (
    64764752532480000.0,
    32382376266240000.0,
    7771770303897600.0,
    1187353796428800.0,
    129060195264000.0,
    10559470521600.0,
    670442572800.0,
    33522128640.0,
    1323241920.0,
    40840800.0,
    960960.0,
    16380.0,
    182.0,
    1.0,
)


def _pade_coefficients(degree: int) -> list[float]:
    """b_j = (2m - j)! m! / ((2m)! j! (m - j)!) scaled so b_m = 1 (exact integers here)."""
    c = [1.0]
    for j in range(1, degree + 1):
        c.append(c[-1] * (degree - j + 1) / (j * (2 * degree - j + 1)))
    top = c[-1]
    return [v / top for v in c]


def expm(matrix: np.ndarray) -> np.ndarray:
    """The matrix exponential by scaling and squaring with a diagonal Pade approximant
    (Higham 2005, the algorithm of scipy.linalg.expm before its 2009 refinement): exact to
    double precision (tests/sim/test_lti_exact.py against scipy.linalg.expm). Here so that a
    simulated run does not import scipy.linalg (twice `import numpy`, issue 34)."""
    a = np.asarray(matrix, dtype=float)
    n = a.shape[0]
    identity = np.eye(n)
    if n == 0:
        return identity
    norm = float(np.max(np.sum(np.abs(a), axis=0)))
    for degree, theta in _PADE_THETA:
        if norm <= theta:
            c = _pade_coefficients(degree)
            a2 = a @ a
            powers = [identity, a2]
            for _ in range(2, degree // 2 + 1):
                powers.append(powers[-1] @ a2)
            u = a @ sum(c[2 * k + 1] * powers[k] for k in range(degree // 2 + 1))
            v = sum(c[2 * k] * powers[k] for k in range(degree // 2 + 1))
            return np.linalg.solve(v - u, v + u)
    squarings = max(0, int(np.ceil(np.log2(norm / _THETA_13))))
    a = a / 2.0**squarings
    c13 = _PADE_13
    a2 = a @ a
    a4 = a2 @ a2
    a6 = a4 @ a2
    u = a @ (
        a6 @ (c13[13] * a6 + c13[11] * a4 + c13[9] * a2)
        + c13[7] * a6
        + c13[5] * a4
        + c13[3] * a2
        + c13[1] * identity
    )
    v = (
        a6 @ (c13[12] * a6 + c13[10] * a4 + c13[8] * a2)
        + c13[6] * a6
        + c13[4] * a4
        + c13[2] * a2
        + c13[0] * identity
    )
    result = np.linalg.solve(v - u, v + u)
    for _ in range(squarings):
        result = result @ result
    return result


def _zoh(a: np.ndarray, b: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(e^{A t}, Gamma(t) B) via one block-matrix exponential (Van Loan)."""
    n, m = a.shape[0], b.shape[1]
    block = np.zeros((n + m, n + m))
    block[:n, :n] = a * t
    block[:n, n:] = b * t
    exponential = expm(block)
    return exponential[:n, :n], exponential[:n, n:]


class Network:
    """A single-input network of continuous models; every signal is C x + D u.

    `add(name, model, source)` feeds a model from an existing signal (or the input);
    `combine(name, terms)` makes a weighted sum of signals. Shared parts are simulated once.
    """

    INPUT = "input"

    def __init__(self) -> None:
        self.a = np.zeros((0, 0))
        self.b = np.zeros((0, 1))
        self.signals: dict[str, tuple[np.ndarray, float]] = {self.INPUT: (np.zeros(0), 1.0)}

    def add(self, name: str, model: Model, source: str = INPUT) -> Network:
        c_src, d_src = self._padded(source)
        a2, b2, c2, d2 = model.state_space()
        n1, n2 = self.a.shape[0], a2.shape[0]
        a = np.zeros((n1 + n2, n1 + n2))
        a[:n1, :n1] = self.a
        a[n1:, :n1] = b2 @ c_src[None, :]
        a[n1:, n1:] = a2
        self.a = a
        self.b = np.vstack([self.b, b2 * d_src])
        c_new = np.concatenate([float(d2[0, 0]) * c_src, c2[0]])
        self.signals[name] = (c_new, float(d2[0, 0]) * d_src)
        return self

    def combine(self, name: str, terms: dict[str, float]) -> Network:
        n = self.a.shape[0]
        c, d = np.zeros(n), 0.0
        for signal, weight in terms.items():
            c_s, d_s = self._padded(signal)
            c, d = c + weight * c_s, d + weight * d_s
        self.signals[name] = (c, d)
        return self

    def _padded(self, name: str) -> tuple[np.ndarray, float]:
        try:
            c, d = self.signals[name]
        except KeyError:
            raise ValueError(f"network: no signal {name!r}") from None
        padded = np.zeros(self.a.shape[0])
        padded[: c.size] = c
        return padded, d


class MultiZoh:
    """A `Network` run at `sample_rate_hz` behind a ZOH; outputs are named signals, each
    optionally sampled a delay after the input instant (< 1/fs). Modal form, one recursion per
    real pole or conjugate pole pair; state carries across blocks."""

    def __init__(
        self,
        network: Network,
        outputs: dict[str, tuple[str, float]],
        sample_rate_hz: float,
    ):
        period = 1.0 / sample_rate_hz
        a, b = network.a, network.b
        n = a.shape[0]
        self.names = tuple(outputs)
        c_rows, d_vals = [], []
        for signal, delay in outputs.values():
            c, d = network._padded(signal)
            if not 0.0 <= delay < period:
                raise ValueError(f"output {signal!r}: delay must be within one sample period")
            if delay > 0.0 and n:
                e_tau, gamma_b = _zoh(a, b, delay)
                c, d = c @ e_tau, d + float(c @ gamma_b[:, 0])
            c_rows.append(c)
            d_vals.append(d)
        self._direct = np.array(d_vals)
        if n == 0:
            self._poles = np.zeros(0, complex)
            self._inputs = np.zeros(0, complex)
            self._outputs = np.zeros((len(self.names), 0), complex)
        else:
            ad, bd = _zoh(a, b, period)
            poles, vectors = np.linalg.eig(ad)
            inputs = np.linalg.solve(vectors, bd[:, 0])
            out = np.array(c_rows) @ vectors
            scale = np.maximum(np.abs(poles), 1e-300)
            upper = poles.imag > 1e-12 * scale
            real = np.abs(poles.imag) <= 1e-12 * scale
            keep = upper | real
            weight = np.where(upper, 2.0, 1.0)[keep]
            self._poles = poles[keep]
            self._inputs = inputs[keep]
            self._outputs = out[:, keep] * weight
        self._build_real_sections()

    def _build_real_sections(self) -> None:
        """Real second-order sections equal to the complex modal recursions.

        A mode m[n] = p m[n-1] + u[n-1] of a conjugate pair is m = q - conj(p) q[n-1] with
        q = z^-1 / (1 - 2 Re(p) z^-1 + |p|^2 z^-2) u, a real all-pole section; so the real part
        of its weighted contribution is Re(W) q[n] - Re(W conj(p)) q[n-1]. A real pole is a
        first-order real section. Real arithmetic runs several times faster than a complex
        `lfilter`; the outputs agree to rounding (tests/sim/test_fast_path.py).
        """
        weights = self._outputs * self._inputs  # (outputs, modes), the input gain folded in
        sections, columns, shifted = [], [], []
        for k, pole in enumerate(self._poles):
            w = weights[:, k]
            if abs(pole.imag) > 1e-12 * max(abs(pole), 1e-300):
                sections.append([0.0, 1.0, 0.0, 1.0, -2.0 * pole.real, abs(pole) ** 2])
                columns.append(w.real)
                shifted.append(-(w * np.conj(pole)).real)
            else:
                sections.append([0.0, 1.0, 0.0, 1.0, -pole.real, 0.0])
                columns.append(w.real)
                shifted.append(np.zeros(w.size))
        k, outputs = len(sections), len(self.names)
        self._sections = np.array(sections, dtype=float).reshape(k, 1, 6)
        # outputs = mix[:outputs] @ q[n] + mix[outputs:] @ q[n-1], q the sections' outputs
        self._mix = np.vstack(
            [
                np.array(columns, dtype=float).reshape(k, outputs).T,
                np.array(shifted, dtype=float).reshape(k, outputs).T,
            ]
        )
        self._zi = np.zeros((k, 1, 1, 2))  # each section's state, as _sosfilt wants it
        self._last = np.zeros(k)  # each section's last output (q[n-1] across blocks)

    def process(self, u: np.ndarray) -> dict[str, np.ndarray]:
        """Outputs for the next block of input samples; the state carries to the next call."""
        u = np.ascontiguousarray(u, dtype=float)
        k, n, outputs = self._sections.shape[0], u.size, len(self.names)
        if k == 0 or n == 0:
            y = np.multiply.outer(self._direct, u)
        else:
            q = np.empty((k, n))
            q[:] = u
            for i in range(k):
                _sosfilt_inplace(self._sections[i], q[i : i + 1], self._zi[i])
            mixed = np.empty((2 * outputs, n))
            for first in range(0, n, _MIX_CHUNK):  # small products: BLAS stays on one thread
                last = first + _MIX_CHUNK
                np.matmul(self._mix, q[:, first:last], out=mixed[:, first:last])
            y = mixed[:outputs]
            y[:, 1:] += mixed[outputs:, :-1]
            y[:, 0] += self._mix[outputs:] @ self._last
            y += np.multiply.outer(self._direct, u)
            self._last[:] = q[:, -1]
        return dict(zip(self.names, y, strict=True))

    def reset(self) -> None:
        """Back to rest (zero state)."""
        self._zi[:] = 0.0
        self._last[:] = 0.0

    def discrete_response(
        self, name: str, frequency_hz: np.ndarray, sample_rate_hz: float
    ) -> np.ndarray:
        """Steady-state response of output `name` to a sampled sine (ZOH and delay included)."""
        row = self.names.index(name)
        z = np.exp(2j * np.pi * np.asarray(frequency_hz, dtype=float) / sample_rate_hz)
        out = np.full(z.shape, self._direct[row], dtype=complex)
        for k, pole in enumerate(self._poles):
            h, g = self._outputs[row, k], self._inputs[k]
            if abs(pole.imag) > 1e-12 * max(abs(pole), 1e-300):  # a conjugate pair, weight 2
                half = h / 2 * g
                out += half / (z - pole) + np.conj(half) / (z - np.conj(pole))
            else:
                out += h * g / (z - pole)
        return out


class ZohFilter:
    """One model behind a ZOH at `sample_rate_hz`, output sampled `delay_s` late: a `MultiZoh`
    of one output, its block in and its block out (no dict of named outputs)."""

    def __init__(self, model: Model, sample_rate_hz: float, delay_s: float = 0.0):
        self._zoh = MultiZoh(Network().add("y", model), {"y": ("y", delay_s)}, sample_rate_hz)
        self.model = model

    def process(self, u: np.ndarray) -> np.ndarray:
        """The output for the input block `u`; state carries across blocks."""
        return self._zoh.process(u)["y"]

    def reset(self) -> None:
        """Back to rest (zero state)."""
        self._zoh.reset()

    def discrete_response(self, frequency_hz: np.ndarray, sample_rate_hz: float) -> np.ndarray:
        """Steady-state response to a sampled sine (ZOH and delay included)."""
        return self._zoh.discrete_response("y", frequency_hz, sample_rate_hz)
