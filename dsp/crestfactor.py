"""Crest factor of periodic multisine excitation and phase optimisation to minimise it.

One period of N samples of a multisine with lines on DFT bins m_k (seed paper eq. 13):

    x(i) = sum_k A_k sin(2 pi m_k i / N + phi_k),   i = 0 .. N-1,

with amplitudes A_k in the unit of the signal (e.g. m/s^2 peak per line) and phases phi_k in
rad. The crest factor is max|x(i)| / rms(x) over the N samples (dimensionless).

Methods and references
----------------------
* Schroeder phases: M. R. Schroeder, "Synthesis of low-peak-factor signals and binary
  sequences with low autocorrelation", IEEE Trans. Inf. Theory 16(1), 85-89, 1970.
* Lp-norm (Chebyshev) phase optimisation: P. Guillaume, J. Schoukens, R. Pintelon and
  I. Kollar, "Crest-factor minimization using nonlinear Chebyshev approximation methods",
  IEEE Trans. Instrum. Meas. 40(6), 982-989, 1991. The p-norm of x is minimised for
  increasing p, which tends to the peak value (the infinity norm) as p grows.
* The time/frequency clipping ("swapping") algorithm of E. Van der Ouderaa, J. Schoukens and
  J. Renneboog, "Peak factor minimization using a time-frequency domain swapping algorithm",
  IEEE Trans. Instrum. Meas. 37(1), 145-147, 1988, was measured on the seed plans and not
  kept: with 25 lines among 6000 bins almost all clipping energy falls between the lines, so
  200 iterations only took the piezo plan from 3.70 to 3.64 (the Lp method reaches 2.48).

Sparse, logarithmically spaced plans (ISO 266 thirds of an octave) have many local optima
of the crest factor, and their best values are well above the ~1.4-1.5 of dense multisines:
lines far apart in frequency cannot avoid adding their peaks. Measured on the seed plans
(equal amplitudes): piezo (25 lines, N = 12000) best 2.484, next local optima 2.506-2.52;
capacitive (27 lines, N = 24000) best 2.603. Several hundred random starts, basin hopping
with band time-shifts and simulated annealing found nothing lower, so a crest factor <= 2.5
is reachable for the piezo plan (only in its best basin) but not for the capacitive plan.
`optimise_phases` therefore screens many starts cheaply and refines only the best ones.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Sequence

import numpy as np

__all__ = [
    "ALGORITHM_VERSION",
    "DEFAULT_MAX_EVALUATIONS",
    "MAX_WORK_SAMPLES",
    "OPTIMISER_BYTES_PER_SAMPLE",
    "PEAK_GRID_MAX",
    "crest_factor",
    "evaluation_cap",
    "optimise_phases",
    "peak_grid_samples",
    "random_phases",
    "schroeder_phases",
    "synthesize",
]

TWO_PI = 2.0 * np.pi

#: Changes whenever optimise_phases may return other phases for the same arguments (a stored
#: result, e.g. app.procedure.phases, is keyed by it). 1: CPU-time safety cap; 2: counts only,
#: amplitudes normalised to their maximum first; 3: the evaluations bounded by the period too
#: (MAX_WORK_SAMPLES; the same phases as 2 for periods up to 24000 samples).
ALGORITHM_VERSION = 3

# Work schedule of optimise_phases. Every stage is bounded by counts (starts, norms, L-BFGS
# iterations, objective evaluations), so the result depends only on the inputs and the seed,
# never on machine speed or load: no clock is read.
_SCREEN_SAMPLES = 600_000  # starts x period samples screened: 50 starts for N = 12000
_MIN_STARTS, _MAX_STARTS = 8, 64
_P_SCREEN = (4.0, 16.0)  # every start is taken to a minimum of these norms in turn
_SCREEN_FTOL = 1e-6  # enough to rank the 16-norm minima (their spread is ~1e-3)
_N_REFINE = 2  # starts with the lowest distinct 16-norm that are refined further
_SAME_OPTIMUM = 1e-5  # J_16 values closer than this are taken as the same optimum
_P_REFINE = (32.0, 64.0, 128.0, 256.0, 512.0, 1024.0)
_REFINE_FTOL = 1e-8
_MAXITER = 200  # L-BFGS iterations per norm
_SCREEN_SHARE = 0.7  # share of max_evaluations after which no further start is screened
#: Objective evaluations (one FFT pair, or one line-product sum, each) after which the best
#: phases so far are returned. The seed plans need 2100-4500 (bench/crest_factor.py); the cap
#: only bounds the work for plans far off that (about 1 ms each for N = 12000).
DEFAULT_MAX_EVALUATIONS = 20_000
#: Objective evaluations x period samples the optimisation may spend (issue 33): the cap of
#: the capacitive seed plan (N = 24000). A longer period gets proportionally fewer evaluations
#: (`evaluation_cap`), so the work is about 4.8e8 sample-evaluations, 20-25 s of CPU at the
#: 40-47 ns per sample-evaluation measured for N = 12000 to 2 000 000, whatever the period.
MAX_WORK_SAMPLES = DEFAULT_MAX_EVALUATIONS * 24_000
#: Bytes of memory the optimisation needs per period sample (its work buffers and the FFT's;
#: an upper estimate): app.procedure.capacity refuses a plan the machine cannot hold.
OPTIMISER_BYTES_PER_SAMPLE = 96


def evaluation_cap(period_samples: int, max_evaluations: int = DEFAULT_MAX_EVALUATIONS) -> int:
    """The objective evaluations `optimise_phases` makes at most for a period of
    `period_samples`: `max_evaluations`, fewer for a period over MAX_WORK_SAMPLES /
    max_evaluations (at least 2: Schroeder's phases are then kept unless one step helps)."""
    return max(2, min(int(max_evaluations), MAX_WORK_SAMPLES // max(int(period_samples), 1)))


# Predicted peaks are taken on at most this many points a period, or 16 per period of the
# highest line when more (issue 33: a 2^24-sample period oversampled 8x took 4.3 GB and
# minutes per waveform)
PEAK_GRID_MAX = 2**23


def peak_grid_samples(
    period_samples: int, bins: Sequence[int] | np.ndarray, oversampling: int = 8
) -> int:
    """Points per period of the grid predicted peaks are taken on: `oversampling` times
    the period (dsp.multisine.PEAK_OVERSAMPLING), or for a long period `PEAK_GRID_MAX` (at
    least 16 per period of the highest line): the same continuous waveform, sampled finely
    enough to see its peaks."""
    n = int(period_samples) * oversampling
    if n <= PEAK_GRID_MAX:
        return n
    top = int(np.max(np.asarray(bins))) if len(bins) else 1
    return min(n, max(PEAK_GRID_MAX, 16 * top))


def crest_factor(x: np.ndarray) -> float:
    """Crest factor max|x| / rms(x) of the samples x (dimensionless, >= 1)."""
    x = np.asarray(x, dtype=float)
    if x.ndim != 1 or x.size == 0:
        raise ValueError(f"crest_factor: needs a non-empty 1-D signal, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("crest_factor: signal contains NaN or infinity")
    rms = float(np.sqrt(np.mean(x * x)))
    if rms == 0.0:
        raise ValueError("crest_factor: signal is identically zero")
    return float(np.max(np.abs(x))) / rms


def synthesize(
    bins: np.ndarray,
    amplitudes: np.ndarray,
    phases_rad: np.ndarray,
    period_samples: int,
) -> np.ndarray:
    """One period x(i) = sum_k A_k sin(2 pi m_k i / N + phi_k), i = 0..N-1 (seed eq. 13).

    `bins` are the DFT bins m_k (integers, 0 < m_k < N/2, distinct), `amplitudes` A_k are
    peak values in the unit of the returned signal, `phases_rad` phi_k in rad, N =
    `period_samples`. Computed with an inverse real FFT of the sparse spectrum
    X[m_k] = (N/2) A_k exp(j (phi_k - pi/2)).
    """
    n = _check_period(period_samples)
    m = _check_bins(bins, n)
    a = _check_per_line(amplitudes, m.size, "amplitudes")
    phi = _check_per_line(phases_rad, m.size, "phases_rad")
    spectrum = np.zeros(n // 2 + 1, dtype=complex)
    spectrum[m] = (n / 2.0) * a * np.exp(1j * (phi - np.pi / 2.0))
    return np.fft.irfft(spectrum, n=n)


def schroeder_phases(amplitudes: np.ndarray) -> np.ndarray:
    """Schroeder (1970) phases in rad, in [0, 2 pi), for lines with the given amplitudes.

    phi_k = phi_1 - 2 pi sum_{l<k} (k - l) p_l with power shares p_l = A_l^2 / sum A^2, lines
    taken in the order given, and phi_1 = 0. (Schroeder writes cosines; with the sines of
    eq. 13 this is his signal delayed by a quarter period of each line, which changes the
    waveform only through the choice of phi_1, itself arbitrary in his formula.)
    """
    a = np.asarray(amplitudes, dtype=float)
    if a.ndim != 1 or a.size == 0 or not np.all(np.isfinite(a)):
        raise ValueError("schroeder_phases: amplitudes must be a non-empty finite 1-D array")
    power = a * a
    total = float(np.sum(power))
    if total <= 0.0:
        raise ValueError("schroeder_phases: amplitudes are all zero")
    p = power / total
    # sum_{l<k} (k - l) p_l = k * P_{k-1} - Q_{k-1} with P, Q cumulative sums of p_l, l p_l
    k = np.arange(a.size, dtype=float)
    cum_p = np.concatenate(([0.0], np.cumsum(p)[:-1]))
    cum_lp = np.concatenate(([0.0], np.cumsum(k * p)[:-1]))
    return np.mod(-TWO_PI * (k * cum_p - cum_lp), TWO_PI)


def random_phases(n: int, rng: np.random.Generator) -> np.ndarray:
    """n independent phases in rad, uniform in [0, 2 pi)."""
    if n < 0:
        raise ValueError(f"random_phases: n must be >= 0, got {n}")
    return rng.uniform(0.0, TWO_PI, size=n)


def optimise_phases(
    bins: np.ndarray,
    amplitudes: np.ndarray,
    period_samples: int,
    *,
    seed: int = 0,
    max_evaluations: int = DEFAULT_MAX_EVALUATIONS,
) -> np.ndarray:
    """Phases in rad, in [0, 2 pi), that minimise the crest factor of `synthesize(...)`.

    `bins` and `amplitudes` (> 0, any unit) as for `synthesize`; N = `period_samples`.
    Only the amplitudes' ratios matter: they are divided by their maximum first, so the same
    lines at any level give bit-identical phases.
    Method (Guillaume et al. 1991): minimise J_p = log((mean|x|^p)^(1/p) / rms), which tends
    to the log crest factor as p grows, with L-BFGS and the analytic gradient (_lbfgs,
    _LpProblem), for increasing p:

    1. Screening: Schroeder's phases and random starts (numpy Generator seeded with `seed`;
       50 starts for N = 12000, 25 for N = 24000: starts x N = 600000, within 8-64) are each
       taken to a minimum of J_4 (computed in the frequency domain from the (2K)^2 products
       of lines, ~5x cheaper than the FFTs) and then of J_16. Which local optimum a start
       ends in is decided by then: the lowest J_16 marks the best final crest factor.
    2. Refinement: the 2 starts with the lowest distinct J_16 go through p = 32, ..., 1024.
    3. The phases with the lowest crest factor of all synthesised waveforms are returned.

    The clipping algorithm (Van der Ouderaa et al. 1988) is not used: see the module notes.

    The work is bounded by counts only (starts, norms, L-BFGS iterations and
    `max_evaluations` objective evaluations, fewer for a long period: `evaluation_cap`, so
    that evaluations x N stay within MAX_WORK_SAMPLES; past 70 % of these no further start
    is screened, past all of them the best phases so far are returned); no clock is read.
    The result is therefore a function of the arguments alone: the same on every call, at any
    machine load and speed (given the same numpy floating-point kernels). The seed plans stop
    on their own well before the default evaluation cap.

    Measured on the development machine (2-core AMD EPYC VM, docs/benchmarks.md): 0.5-0.9 s
    of CPU for the piezo plan (crest factor 2.486), 0.55-0.85 s for the capacitive plan
    (2.605) and 0.5-0.9 s for the piezo plan with 1/f amplitudes (2.162; Schroeder 2.95).
    """
    n = _check_period(period_samples)
    m = _check_bins(bins, n)
    a = _check_per_line(amplitudes, m.size, "amplitudes")
    if np.any(a <= 0.0):
        bad = m[np.flatnonzero(a <= 0.0)[0]]
        raise ValueError(f"optimise_phases: amplitude of bin {bad} must be > 0")
    if isinstance(max_evaluations, bool) or not (
        int(max_evaluations) == max_evaluations and max_evaluations >= 1
    ):
        raise ValueError(
            f"optimise_phases: max_evaluations must be an integer >= 1, got {max_evaluations!r}"
        )
    if m.size == 1:
        return np.zeros(1)

    a = a / np.max(a)  # only the ratios matter: the same phases at any level
    max_evaluations = evaluation_cap(n, int(max_evaluations))
    rng = np.random.default_rng(seed)
    n_starts = min(max(_SCREEN_SAMPLES // n, _MIN_STARTS), _MAX_STARTS)
    starts = [schroeder_phases(a)] + [random_phases(m.size, rng) for _ in range(n_starts - 1)]
    screening = max(1, int(_SCREEN_SHARE * max_evaluations))
    problem = _LpProblem(m, a, n, max_evaluations=screening)
    problem.evaluate(starts[0])  # never worse than Schroeder's phases

    screened: list[tuple[float, np.ndarray]] = []
    try:
        for phases in starts:
            for p in _P_SCREEN:
                value, phases = problem.minimise(phases, p, ftol=_SCREEN_FTOL)
            screened.append((value, phases))
    except _BudgetExhausted:
        pass
    screened.sort(key=lambda item: item[0])
    chosen: list[tuple[float, np.ndarray]] = []
    for value, phases in screened:  # symmetric copies of one optimum share their J_16
        if len(chosen) < _N_REFINE and all(abs(value - v) > _SAME_OPTIMUM for v, _ in chosen):
            chosen.append((value, phases))
    if not chosen:  # the cap came before the first start was screened: refine the best so far
        chosen.append((np.inf, problem.best_phases))
    problem.max_evaluations = int(max_evaluations)
    try:
        for _, phases in chosen:
            for p in _P_REFINE:
                _, phases = problem.minimise(phases, p, ftol=_REFINE_FTOL)
    except _BudgetExhausted:
        pass
    return np.mod(problem.best_phases, TWO_PI)


class _BudgetExhausted(Exception):
    """Raised before an objective evaluation once `max_evaluations` of them were made."""


class _LpProblem:
    """p-norm objective of the unit-rms multisine as a function of the phases (rad).

    Tracks the lowest crest factor over every waveform it synthesises, and counts the
    objective evaluations (`objective_evaluations`): past `max_evaluations` of them the next
    one raises _BudgetExhausted.
    """

    def __init__(self, bins: np.ndarray, amplitudes: np.ndarray, n: int, *, max_evaluations: int):
        self.bins = bins
        self.n = n
        self.max_evaluations = max_evaluations
        self.objective_evaluations = 0
        rms = float(np.sqrt(0.5 * np.sum(amplitudes**2)))
        self.amp = amplitudes / rms  # amplitudes of the unit-rms signal
        self._coef = 0.5 * n * self.amp
        # L-BFGS works on u_k = s_k phi_k, s_k = A_k / max A: the objective's sensitivity to a
        # phase grows with the line's amplitude, so this balances unequal amplitudes (it cut
        # the iterations 2-4 fold for 1/f amplitudes) and changes nothing for equal ones.
        self.precond = amplitudes / np.max(amplitudes)
        self._spectrum = np.zeros(n // 2 + 1, dtype=complex)
        self._buf_w, self._buf_wq, self._buf_tmp = np.empty(n), np.empty(n), np.empty(n)
        self._buf_x = np.empty(n)
        self._buf_spec = np.empty(n // 2 + 1, dtype=complex)
        self.best_crest = np.inf
        self.best_phases = np.zeros(bins.size)
        self.evaluations = 0
        # 4-norm in the frequency domain: x^2 has lines at (f_s + f_t) mod N for the 2K
        # signed line frequencies f_s = +-m_k; its mean square follows from Parseval.
        k = bins.size
        self._use_pairs = 4 * k * k <= n // 2
        if self._use_pairs:
            signed = np.concatenate((bins, -bins))
            pair_freq = np.mod(signed[:, None] + signed[None, :], n).ravel()
            unique, self._pair_index = np.unique(pair_freq, return_inverse=True)
            self._n_pair_freqs = unique.size

    def waveform(self, phases: np.ndarray) -> np.ndarray:
        """One period of the unit-rms signal."""
        self._spectrum[self.bins] = self._coef * np.exp(1j * (phases - np.pi / 2.0))
        return _irfft(self._spectrum, self.n, out=self._buf_x)

    def evaluate(self, phases: np.ndarray) -> float:
        """Crest factor of the phases (also recorded as a candidate)."""
        peak = float(np.max(np.abs(self.waveform(phases))))
        self._record(peak, phases)
        return peak

    def _record(self, crest: float, phases: np.ndarray) -> None:
        self.evaluations += 1
        if crest < self.best_crest:
            self.best_crest = crest
            self.best_phases = np.array(phases, dtype=float)

    def _count_evaluation(self) -> None:
        if self.objective_evaluations >= self.max_evaluations:
            raise _BudgetExhausted
        self.objective_evaluations += 1

    def lp_value_and_grad(self, phases: np.ndarray, p: float) -> tuple[float, np.ndarray]:
        """log of the p-mean (mean|x|^p)^(1/p) of the unit-rms signal and its gradient (1/rad).

        With G = rfft(|x|^(p-2) x): d/dphi_k sum_i |x_i|^p = p A_k Re(exp(j phi_k) G*[m_k]).
        """
        self._count_evaluation()
        x = self.waveform(phases)
        peak = max(float(x.max()), -float(x.min()))
        self._record(peak, phases)
        x *= 1.0 / peak  # now y = x / peak, |y| <= 1: no overflow for any p
        w = np.multiply(x, x, out=self._buf_w)  # y^2
        q = 0.5 * p - 1.0
        if q == 1.0:
            wq = w
        else:  # the floor keeps w^q out of the slow subnormal range; those terms are < 1e-290
            np.maximum(w, 1e-290 ** (1.0 / q), out=w)
            wq = _power(w, q, out=self._buf_wq, scratch=self._buf_tmp)
        total = float(np.multiply(wq, w, out=self._buf_tmp).sum())  # sum |y|^p >= 1
        np.multiply(wq, x, out=self._buf_tmp)  # |y|^(p-2) y
        g = _rfft(self._buf_tmp, out=self._buf_spec)[self.bins]
        grad = self.amp * (np.cos(phases) * g.real + np.sin(phases) * g.imag) / (peak * total)
        value = np.log(peak) + np.log(total / self.n) / p
        return float(value), grad

    def l4_value_and_grad(self, phases: np.ndarray) -> tuple[float, np.ndarray]:
        """Same as lp_value_and_grad(phases, 4) but from the line products, without an FFT.

        Exact on the N-sample grid; only used when 4 K^2 <= N/2 where it is the cheaper way.
        """
        self._count_evaluation()
        k = self.bins.size
        half = 0.5 * self.amp * np.exp(1j * (phases - np.pi / 2.0))
        c = np.concatenate((half, half.conj()))  # x(i) = sum_s c_s exp(j 2 pi f_s i / N)
        prod = np.multiply.outer(c, c).ravel()
        idx = self._pair_index
        sq_re = np.bincount(idx, prod.real, self._n_pair_freqs)  # spectrum of x^2
        sq_im = np.bincount(idx, prod.imag, self._n_pair_freqs)
        mean4 = float(np.sum(sq_re * sq_re) + np.sum(sq_im * sq_im))  # mean(x^4), Parseval
        # d mean4 / d phi_k = 4 sum_t Re(j c_k c_t C*) - (same for the conjugate line)
        w = (sq_im[idx] * prod.real - sq_re[idx] * prod.imag).reshape(2 * k, 2 * k).sum(axis=1)
        grad = (w[:k] - w[k:]) / mean4
        return 0.25 * np.log(mean4), grad

    def minimise(self, phases: np.ndarray, p: float, ftol: float) -> tuple[float, np.ndarray]:
        """Local minimum of the p-norm objective from `phases`: (value, phases)."""
        scale = self.precond

        def fun(u: np.ndarray) -> tuple[float, np.ndarray]:
            phi = u / scale
            if p == 4.0 and self._use_pairs:
                value, grad = self.l4_value_and_grad(phi)
            else:
                value, grad = self.lp_value_and_grad(phi, p)
            return value, grad / scale

        value, u = _lbfgs(fun, phases * scale, _MAXITER, ftol=ftol)
        return value, u / scale


def _lbfgs(
    fun: Callable[[np.ndarray], tuple[float, np.ndarray]],
    x0: np.ndarray,
    maxiter: int,
    *,
    memory: int = 5,
    ftol: float = 1e-10,
    gtol: float = 1e-9,
) -> tuple[float, np.ndarray]:
    """Minimise fun (returning value and gradient) by L-BFGS with a backtracking line search.

    Limited-memory BFGS two-loop recursion (J. Nocedal and S. J. Wright, Numerical
    Optimization, 2nd ed., Springer 2006, algorithms 7.4 and 7.5) with an Armijo line search;
    curvature pairs with s.y <= 0 are skipped. Used instead of scipy's L-BFGS-B, whose
    internal BLAS calls go through OpenBLAS threads: on the 2-core development machine they
    took 1-5 ms per iteration (more than the FFTs) when another process was busy, and their
    spinning adds to the process CPU time. This one needs only numpy vector operations.
    Returns (value, x) after at most `maxiter` iterations.
    """
    x = np.array(x0, dtype=float)
    f, g = fun(x)
    pairs: list[tuple[np.ndarray, np.ndarray, float]] = []
    for _ in range(maxiter):
        d = -g
        alphas = []
        for s, y, rho in reversed(pairs):
            a = rho * _dot(s, d)
            d = d - a * y
            alphas.append(a)
        if pairs:
            s, y, rho = pairs[-1]
            d = d * (1.0 / (rho * _dot(y, y)))
        else:
            d = d * min(1.0, 0.1 / max(float(np.max(np.abs(g))), 1e-300))
        for (s, y, rho), a in zip(pairs, reversed(alphas), strict=True):
            d = d + (a - rho * _dot(y, d)) * s
        slope = _dot(g, d)
        if not slope < 0.0:  # not a descent direction: restart from steepest descent
            pairs.clear()
            d = -g * min(1.0, 0.1 / max(float(np.max(np.abs(g))), 1e-300))
            slope = _dot(g, d)
            if not slope < 0.0:
                break
        step = 1.0
        for _ in range(30):
            x_new = x + step * d
            f_new, g_new = fun(x_new)
            if f_new <= f + 1e-4 * step * slope:
                break
            step *= 0.5
        else:
            break
        s = x_new - x
        y = g_new - g
        sy = _dot(s, y)
        if sy > 1e-12 * np.sqrt(_dot(s, s) * _dot(y, y)):
            pairs.append((s, y, 1.0 / sy))
            if len(pairs) > memory:
                pairs.pop(0)
        decrease = f - f_new
        x, f, g = x_new, f_new, g_new
        if decrease <= ftol * max(1.0, abs(f)) or float(np.max(np.abs(g))) <= gtol:
            break
    return float(f), x


# numpy >= 2.0 FFTs write into a given array: no fresh period-sized arrays per evaluation,
# whose allocation (page faults after malloc trims) made repeated runs up to 2x slower.
_FFT_HAS_OUT = "out" in inspect.signature(np.fft.rfft).parameters


def _irfft(spectrum: np.ndarray, n: int, out: np.ndarray) -> np.ndarray:
    if _FFT_HAS_OUT:
        return np.fft.irfft(spectrum, n=n, out=out)
    return np.fft.irfft(spectrum, n=n)


def _rfft(x: np.ndarray, out: np.ndarray) -> np.ndarray:
    if _FFT_HAS_OUT:
        return np.fft.rfft(x, out=out)
    return np.fft.rfft(x)


def _power(w: np.ndarray, q: float, out: np.ndarray, scratch: np.ndarray) -> np.ndarray:
    """w**q into `out`; by repeated squaring when q is a positive integer (p = 8, 16, ...),
    several times faster than np.power. `scratch` is overwritten."""
    if q != int(q) or q < 1:
        return np.power(w, q, out=out)
    e = int(q)
    np.copyto(scratch, w)
    first = True
    while e:
        if e & 1:
            if first:
                np.copyto(out, scratch)
                first = False
            else:
                out *= scratch
        e >>= 1
        if e:
            np.multiply(scratch, scratch, out=scratch)
    return out


def _dot(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.add.reduce(a * b))


def _check_period(period_samples: int) -> int:
    n = int(period_samples)
    if n != period_samples or n < 3:
        raise ValueError(f"period_samples must be an integer >= 3, got {period_samples!r}")
    return n


def _check_bins(bins: np.ndarray, n: int) -> np.ndarray:
    raw = np.asarray(bins)
    if raw.ndim != 1 or raw.size == 0:
        raise ValueError(f"bins: need a non-empty 1-D array, got shape {raw.shape}")
    for value in raw.tolist():
        if not np.isfinite(value) or value != round(value):
            raise ValueError(f"bin {value!r}: not an integer")
        if not 0 < value < n / 2:
            raise ValueError(f"bin {value!r}: outside 0 < m < N/2 = {n / 2:g}")
    m = raw.astype(np.int64)
    values, counts = np.unique(m, return_counts=True)
    if np.any(counts > 1):
        raise ValueError(f"bin {int(values[np.argmax(counts > 1)])}: appears more than once")
    return m


def _check_per_line(values: np.ndarray, k: int, name: str) -> np.ndarray:
    v = np.asarray(values, dtype=float)
    if v.shape != (k,):
        raise ValueError(f"{name}: need {k} values (one per bin), got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name}: contains NaN or infinity")
    return v
