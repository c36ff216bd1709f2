"""A triaxial accelerometer from three orientations (issue 36 point 3; SPEC.md section 10a):
the 3 x 3 complex sensitivity matrix per line, the main-axis sensitivities and the transverse
sensitivity ratios with their direction (ISO 16063-31's statement), each with its GUM U.

In orientation o the exciter moves along the sensor's axis o; channel j's run against the
reference gives column o of the matrix: S[j, o] in mV/(m/s^2), complex (its phase in degrees).
The main-axis sensitivity of axis j is S[j, j]; its transverse ratios are T[j, k] =
S[j, k] / S[j, j] (complex, a fraction: magnitude and phase, i.e. sign and direction); its
largest transverse sensitivity is sqrt(|T[j, k]|^2 + |T[j, l]|^2) at the angle
atan2(Re T[j, l], Re T[j, k]) in the plane normal to j, measured from axis k towards axis l
with (j, k, l) cyclic (x: y -> z, y: z -> x, z: x -> y). The angle uses the parts of the
ratios in phase with the main axis: for a tilted sensing axis (transverse response in phase
or in antiphase with the main one) it is atan2(S[j, l], S[j, k]) exactly, the sign of each
ratio giving the direction.

Uncertainty: GUM linear propagation (JCGM 100 5.1), analytic, as dsp.characteristic does for
the deviation ratio (dsp.mcm only validates one line's budget). Inputs per line, from each
channel's stored line result (dsp.calibration.LineResult): the type A (relative, the same on
the in-phase and quadrature parts: circular noise, SPEC.md section 6) with its degrees of
freedom, and the budget's components. In T[j, k] both measurements are channel j at the same
line against the same reference, so the factors they share cancel (reference calibration and
frequency dependence, conditioning amplifier and DAQ gains, temperature; reference and
amplifier phase, channel phase match and skew: `SHARED_KINDS`); the others (mounting,
linearity, residual effects, ...) are independent per mounting. Beyond those, the exciter's
own transverse motion and the mounting's misalignment (`table_transverse`: the table's
acceleration along a transverse axis of the sensor per axial m/s^2, a fraction, each of its
in-phase and quadrature parts) add to T[j, k] directly: in orientation k the table moving
along j by e per axial unit makes channel j read S[j, j] e more. Each scalar statement
(magnitude, phase, largest ratio, angle) gets u by the linearised model, nu_eff by
Welch-Satterthwaite, k from Student t at the runs' coverage probability, U = k u. Pure numpy.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from enum import StrEnum
from typing import Any

import numpy as np

from dsp.annex_a import ComponentKind
from dsp.calibration import Results
from dsp.errors import InputRefused
from dsp.triaxial_lines import AXES, Axis, ChannelLines, check_consistent, check_keys
from dsp.uncertainty import Budget, Component, Quantity, coverage_factor, welch_satterthwaite

__all__ = [
    "AXES",
    "SHARED_KINDS",
    "Axis",
    "AxisResult",
    "ChannelLines",
    "MatrixEntry",
    "Stated",
    "TransverseRatio",
    "TriaxialResult",
    "triaxial_from_lines",
    "triaxial_result",
]


# the factors two measurements of one channel at one line against one reference share: they
# cancel in T[j, k] = S[j, k] / S[j, j] (magnitude kinds, phase kinds)
SHARED_KINDS: dict[Quantity, frozenset[ComponentKind]] = {
    Quantity.MAGNITUDE: frozenset(
        {
            ComponentKind.REFERENCE_CALIBRATION,
            ComponentKind.REFERENCE_FREQUENCY_DEPENDENCE,
            ComponentKind.AMPLIFIER_GAIN,
            ComponentKind.DAQ_GAIN,
            ComponentKind.TEMPERATURE,
        }
    ),
    Quantity.PHASE: frozenset(
        {
            ComponentKind.REFERENCE_PHASE,
            ComponentKind.AMPLIFIER_PHASE,
            ComponentKind.CHANNEL_PHASE_MATCH,
            ComponentKind.SKEW,
        }
    ),
}
NO_TABLE_TERM = (
    "no stated transverse motion of the table (exciter, mounting alignment): the transverse "
    "ratios' U holds the channels' terms only and understates them; state it"
)


def _shared(component: Component, quantity: Quantity) -> bool:
    return bool(component.kind) and all(k in SHARED_KINDS[quantity] for k in component.kind)


@dataclass(frozen=True)
class Stated:
    """Per line (arrays of equal length): a value, its standard uncertainty u, its expanded
    uncertainty U = k u, k and nu_eff; the unit is the holder's (its docstring). NaN where
    not stated."""

    value: np.ndarray
    standard: np.ndarray
    expanded: np.ndarray
    coverage_factor: np.ndarray
    dof: np.ndarray

    def at(self, index: int) -> tuple[float, float, float]:
        """(value, U, k) at one line."""
        return (
            float(self.value[index]),
            float(self.expanded[index]),
            float(self.coverage_factor[index]),
        )


@dataclass(frozen=True)
class TransverseRatio:
    """T[j, k] = S[j, k] / S[j, j] of axis `axis` towards axis `towards`, per line: its
    magnitude in % of the main-axis sensitivity, its phase in degrees (0: in phase with the
    main axis, 180: in antiphase, i.e. towards -k), and its part in phase with the main axis
    (signed, %)."""

    axis: Axis
    towards: Axis
    magnitude_percent: Stated
    phase_deg: Stated
    in_phase_percent: Stated


@dataclass(frozen=True)
class AxisResult:
    """One axis: its main-axis sensitivity S[j, j] (mV/(m/s^2)), phase (degrees) and deviation
    from its reference-frequency value (%), each with U as its own run states them; its two
    transverse ratios; its largest transverse sensitivity (% of the main axis) and that
    direction's angle (degrees, from axis `angle_from` towards axis `angle_towards`)."""

    axis: Axis
    sensitivity_mv_per_ms2: Stated
    phase_deg: Stated
    deviation_percent: Stated
    transverse: tuple[TransverseRatio, TransverseRatio]
    largest_percent: Stated
    angle_deg: Stated
    angle_from: Axis
    angle_towards: Axis
    phase_stated: bool = True


@dataclass(frozen=True)
class MatrixEntry:
    """S[row, column] at the reference frequency: magnitude (mV/(m/s^2)) and phase (degrees)
    with U and k each; an off-diagonal entry's U holds the table's transverse motion too."""

    row: Axis
    column: Axis
    magnitude_mv_per_ms2: float
    magnitude_expanded: float
    magnitude_k: float
    phase_deg: float
    phase_expanded_deg: float
    phase_k: float


@dataclass(frozen=True)
class TriaxialResult:
    """A triaxial sensor's calibration: per line (nominal and actual frequency, Hz) the three
    axes (AxisResult), the 3 x 3 matrix at the reference frequency (`matrix[row][column]`,
    row the channel, column the orientation), the coverage probability (fraction), why a line
    is not stated ("" when it is) and the warnings."""

    nominal_frequency_hz: np.ndarray
    frequency_hz: np.ndarray
    reference_frequency_hz: float
    reference_index: int
    coverage_probability: float
    axes: tuple[AxisResult, AxisResult, AxisResult]
    matrix: tuple[tuple[MatrixEntry, ...], ...]
    not_stated: tuple[str, ...]
    warnings: tuple[str, ...] = field(default=())

    def axis(self, name: str) -> AxisResult:
        """The result of axis `name` ('x', 'y' or 'z')."""
        return self.axes[AXES.index(Axis(name))]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready nested dict (arrays as lists, NaN and inf as None, axes by name)."""
        return _json(asdict(self))


def _json(value: Any) -> Any:
    """`value` with arrays as lists, StrEnums as their strings, NaN and inf as None."""
    if isinstance(value, dict):
        return {str(k): _json(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return [_json(float(v)) for v in value.tolist()]
    if isinstance(value, StrEnum):
        return value.value
    if isinstance(value, bool | int | str) or value is None:
        return value
    number = float(value)
    return number if math.isfinite(number) else None


# ---- the inputs and their checks ---------------------------------------------------------


def triaxial_result(
    runs: Mapping[str, Mapping[str, Results]],
    budget: Budget,
    table_transverse: Budget,
    budgets: Mapping[tuple[str, str], Budget] | None = None,
) -> TriaxialResult:
    """The triaxial result of three orientations' runs: `runs[orientation][channel]` is the
    dsp.calibration.Results of channel (x, y, z) against the reference with the exciter along
    `orientation`; `budget` the runs' type B budget, or each run's own in `budgets[(o, j)]`
    (its measured per-channel terms; the shared kinds, which cancel in a ratio, must then be
    the same in all: InputRefused naming the run otherwise); `table_transverse` the stated
    transverse motion of the table (magnitude components, fraction of the axial acceleration).
    InputRefused names the orientation and channel of an inconsistent input."""
    check_keys(runs)
    own = {(Axis(o), Axis(j)): b for (o, j), b in (budgets or {}).items()}
    if own:
        _check_shared(own)
    lines = {
        (o, j): ChannelLines.from_results(runs[o][j], own.get((o, j), budget))
        for o in AXES
        for j in AXES
    }
    return triaxial_from_lines(lines, budget, table_transverse)


def _shared_part(budget: Budget) -> list[Component]:
    return [c for c in budget.components if _shared(c, c.quantity)]


def _check_shared(budgets: Mapping[tuple[Axis, Axis], Budget]) -> None:
    """InputRefused when two runs' budgets differ in a shared kind (SHARED_KINDS: those
    cancel in T[j, k] only when they are the same stand's)."""
    first = budgets.get((Axis.X, Axis.X))
    if first is None:
        return
    base = _shared_part(first)
    for (o, j), budget in budgets.items():
        if _shared_part(budget) != base:
            raise InputRefused(
                f"triaxial: orientation {o.value!r}, channel {j.value!r}: its budget's shared "
                "terms (reference, amplifier, DAQ gain, temperature; phase: reference, "
                "amplifier, channel match, skew) differ from orientation 'x', channel 'x' "
                "(one stand for the three orientations)"
            )


# ---- the propagation ---------------------------------------------------------------------


@dataclass
class _Inputs:
    """Independent inputs of one line's model: each a vector of its effect (one standard
    uncertainty) on the outputs' Cartesian coordinates, and its dof."""

    effects: list[np.ndarray] = field(default_factory=list)
    dofs: list[float] = field(default_factory=list)

    def add(self, effect: np.ndarray, dof: float) -> None:
        if np.any(effect != 0):
            self.effects.append(effect)
            self.dofs.append(dof)

    def statement(self, gradient: np.ndarray, p: float) -> tuple[float, float, float, float]:
        """(u, U, k, nu_eff) of the scalar output with this gradient."""
        if not self.effects:
            return 0.0, 0.0, math.nan, math.inf
        parts = [abs(float(gradient @ e)) for e in self.effects]
        u = math.hypot(*parts)
        if not math.isfinite(u):
            return math.nan, math.nan, math.nan, math.nan
        nu = welch_satterthwaite(parts, self.dofs) if u > 0 else math.inf
        k = coverage_factor(nu, p)
        return u, k * u, k, nu


def _relative_terms(ch: ChannelLines, i: int, budget: Budget) -> list[tuple[float, float, bool]]:
    """(u, dof, quadrature) of each independent relative error of one measurement S[j, o] at
    line i that the ratio keeps: type A on both parts, the budget's unshared components
    (magnitude: in-phase part, fraction; phase: quadrature part, rad)."""
    f = float(ch.frequency_hz[i])
    u_a, nu_a = float(ch.relative_type_a[i]), float(ch.type_a_dof[i])
    out = [(u_a, nu_a, False), (u_a, nu_a, True)] if math.isfinite(u_a) else []
    for c in budget.at(f, Quantity.MAGNITUDE):
        if not _shared(c, Quantity.MAGNITUDE):
            out.append((c.standard_uncertainty_at(f), c.dof, False))
    for c in budget.at(f, Quantity.PHASE):
        if not _shared(c, Quantity.PHASE):
            out.append((math.radians(c.standard_uncertainty_at(f)), c.dof, True))
    return out


def _own(ch: ChannelLines, budget: Budget) -> Budget:
    """The channel's own run budget, else the one the combination is given."""
    return ch.budget if ch.budget is not None else budget


def _table_terms(table: Budget, f: float) -> list[tuple[float, float]]:
    return [(c.standard_uncertainty_at(f), c.dof) for c in table.at(f, Quantity.MAGNITUDE)]


def _unit(z: complex, quadrature: bool) -> np.ndarray:
    """The Cartesian effect of a relative error on a complex value z: in phase (z) or in
    quadrature (i z)."""
    w = 1j * z if quadrature else z
    return np.array([w.real, w.imag])


def _axis_inputs(
    t_k: complex,
    t_l: complex,
    m_k: ChannelLines,
    m_l: ChannelLines,
    m_j: ChannelLines,
    i: int,
    budget: Budget,
    table: Budget,
) -> _Inputs:
    """The inputs of (Re T_k, Im T_k, Re T_l, Im T_l) of one axis at line i."""
    inputs = _Inputs()
    zero = np.zeros(2)
    for u, dof, quad in _relative_terms(m_k, i, _own(m_k, budget)):
        inputs.add(np.concatenate([u * _unit(t_k, quad), zero]), dof)
    for u, dof, quad in _relative_terms(m_l, i, _own(m_l, budget)):
        inputs.add(np.concatenate([zero, u * _unit(t_l, quad)]), dof)
    for u, dof, quad in _relative_terms(m_j, i, _own(m_j, budget)):  # S[j, j] divides both
        inputs.add(-u * np.concatenate([_unit(t_k, quad), _unit(t_l, quad)]), dof)
    f = float(m_j.frequency_hz[i])
    for u, dof in _table_terms(table, f):  # each orientation's own transverse table motion
        for slot in range(4):
            effect = np.zeros(4)
            effect[slot] = u
            inputs.add(effect, dof)
    return inputs


def _stated(n: int) -> dict[str, np.ndarray]:
    return {key: np.full(n, math.nan) for key in ("value", "standard", "expanded", "k", "dof")}


def _put(store: dict[str, np.ndarray], i: int, value: float, s: tuple[float, ...]) -> None:
    store["value"][i] = value
    store["standard"][i], store["expanded"][i], store["k"][i], store["dof"][i] = s


def _as_stated(store: dict[str, np.ndarray]) -> Stated:
    return Stated(store["value"], store["standard"], store["expanded"], store["k"], store["dof"])


def _next(axis: Axis, step: int = 1) -> Axis:
    return AXES[(AXES.index(axis) + step) % 3]


def triaxial_from_lines(
    lines: Mapping[tuple[Axis, Axis], ChannelLines] | Mapping[tuple[str, str], ChannelLines],
    budget: Budget,
    table_transverse: Budget,
) -> TriaxialResult:
    """The triaxial result from each (orientation, channel)'s ChannelLines (see
    `triaxial_result`, which makes them from stored results)."""
    typed = {(Axis(o), Axis(j)): ch for (o, j), ch in lines.items()}
    for o in AXES:
        for j in AXES:
            if (o, j) not in typed:
                raise InputRefused(
                    f"triaxial: orientation {o.value!r}: channel {j.value!r} missing"
                )
    check_consistent(typed)
    first = typed[(Axis.X, Axis.X)]
    n, p = first.frequency_hz.size, first.coverage_probability
    warnings = [] if table_transverse.components else [NO_TABLE_TERM]
    not_stated = [""] * n
    axes = []
    for j in AXES:
        k, k2 = _next(j), _next(j, 2)
        main = typed[(j, j)]
        m_k, m_l = typed[(k, j)], typed[(k2, j)]  # channel j with the exciter along k, l
        ratio_k = {"magnitude": _stated(n), "phase": _stated(n), "in_phase": _stated(n)}
        ratio_l = {"magnitude": _stated(n), "phase": _stated(n), "in_phase": _stated(n)}
        largest, angle = _stated(n), _stated(n)
        for i in range(n):
            if not (main.stated[i] and m_k.stated[i] and m_l.stated[i]):
                not_stated[i] = not_stated[i] or (
                    "not stated in a run of channel " + j.value + " (outside the reference's "
                    "calibrated range, or too few LSB)"
                )
                continue
            s_j = complex(main.sensitivity[i])
            t_k, t_l = complex(m_k.sensitivity[i]) / s_j, complex(m_l.sensitivity[i]) / s_j
            inputs = _axis_inputs(t_k, t_l, m_k, m_l, main, i, budget, table_transverse)
            for t, store, offset in ((t_k, ratio_k, 0), (t_l, ratio_l, 2)):
                _ratio_statements(t, offset, inputs, store, i, p)
            x = np.array([t_k.real, t_k.imag, t_l.real, t_l.imag])
            size = math.hypot(abs(t_k), abs(t_l))
            grad = x / size if size > 0 else np.zeros(4)
            s = inputs.statement(grad, p)
            if size == 0:  # no transverse: the error's rms in the plane is the u
                s = _isotropic(inputs, p)
            _put(largest, i, 100 * size, _percent(s))
            r2 = t_k.real**2 + t_l.real**2
            if r2 > 0:
                g = np.array([-t_l.real, 0.0, t_k.real, 0.0]) / r2 * math.degrees(1.0)
                _put(angle, i, math.degrees(math.atan2(t_l.real, t_k.real)), inputs.statement(g, p))
        ratios = (
            TransverseRatio(
                j, k, _as_stated(ratio_k["magnitude"]), _as_stated(ratio_k["phase"]),
                _as_stated(ratio_k["in_phase"]),
            ),
            TransverseRatio(
                j, k2, _as_stated(ratio_l["magnitude"]), _as_stated(ratio_l["phase"]),
                _as_stated(ratio_l["in_phase"]),
            ),
        )  # fmt: skip
        axes.append(_axis_result(j, main, ratios, largest, angle, k, k2))
    return TriaxialResult(
        nominal_frequency_hz=first.nominal_frequency_hz.copy(),
        frequency_hz=first.frequency_hz.copy(),
        reference_frequency_hz=float(first.nominal_frequency_hz[first.reference_index]),
        reference_index=first.reference_index,
        coverage_probability=p,
        axes=(axes[0], axes[1], axes[2]),
        matrix=_matrix(typed, first.reference_index, table_transverse),
        not_stated=tuple(not_stated),
        warnings=tuple(warnings),
    )


def _ratio_statements(
    t: complex,
    offset: int,
    inputs: _Inputs,
    store: dict[str, dict[str, np.ndarray]],
    i: int,
    p: float,
) -> None:
    """|T| (%), arg T (degrees) and Re T (%) of one ratio whose Cartesian parts sit at
    `offset`, `offset + 1` of the inputs' vectors."""
    size = abs(t)
    grad = np.zeros(4)
    if size > 0:
        grad[offset : offset + 2] = (t.real / size, t.imag / size)
        s = inputs.statement(grad, p)
    else:
        s = _isotropic(inputs, p, offset)
    _put(store["magnitude"], i, 100 * size, _percent(s))
    if size > 0:
        grad = np.zeros(4)
        grad[offset : offset + 2] = np.array([-t.imag, t.real]) / size**2 * math.degrees(1.0)
        _put(store["phase"], i, math.degrees(math.atan2(t.imag, t.real)), inputs.statement(grad, p))
    grad = np.zeros(4)
    grad[offset] = 1.0
    _put(store["in_phase"], i, 100 * t.real, _percent(inputs.statement(grad, p)))


def _percent(s: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    u, big_u, k, nu = s
    return 100 * u, 100 * big_u, k, nu


def _isotropic(
    inputs: _Inputs, p: float, offset: int | None = None
) -> tuple[float, float, float, float]:
    """At a zero ratio the magnitude has no gradient: its u is the error's rms over the
    plane's coordinates (over one ratio's two at `offset`, else over all four)."""
    slots = range(4) if offset is None else range(offset, offset + 2)
    parts = []
    for s in slots:
        g = np.zeros(4)
        g[s] = 1.0
        parts.append(inputs.statement(g, p))
    u = math.sqrt(sum(x[0] ** 2 for x in parts))
    nu = min((x[3] for x in parts), default=math.inf)
    k = coverage_factor(nu, p) if u > 0 else math.nan
    return u, k * u if u > 0 else 0.0, k, nu


def _axis_result(
    j: Axis,
    main: ChannelLines,
    ratios: tuple[TransverseRatio, TransverseRatio],
    largest: dict[str, np.ndarray],
    angle: dict[str, np.ndarray],
    k: Axis,
    k2: Axis,
) -> AxisResult:
    """The main axis as its run states it, with the ratios and the largest transverse."""
    s = np.abs(main.sensitivity)
    ok = main.stated
    nan = np.where(ok, 1.0, math.nan)
    u_s = s * main.relative_standard * nan
    phase_u = main.phase_expanded_deg / main.phase_coverage_factor
    return AxisResult(
        axis=j,
        sensitivity_mv_per_ms2=Stated(
            s * nan, u_s, s * main.relative_expanded * nan, main.coverage_factor * nan,
            main.dof * nan,
        ),
        phase_deg=Stated(
            np.degrees(np.angle(main.sensitivity)) * nan, phase_u * nan,
            main.phase_expanded_deg * nan, main.phase_coverage_factor * nan, main.dof * nan,
        ),
        deviation_percent=Stated(
            main.deviation_percent * nan,
            main.deviation_expanded_percent / main.coverage_factor * nan,
            main.deviation_expanded_percent * nan, main.coverage_factor * nan, main.dof * nan,
        ),
        transverse=ratios,
        largest_percent=_as_stated(largest),
        angle_deg=_as_stated(angle),
        angle_from=k,
        angle_towards=k2,
        phase_stated=main.phase_stated,
    )  # fmt: skip


def _matrix(
    typed: Mapping[tuple[Axis, Axis], ChannelLines], i: int, table: Budget
) -> tuple[tuple[MatrixEntry, ...], ...]:
    """S[row, column] at line i (the reference line): a diagonal entry as its run states it;
    an off-diagonal one with the table's transverse motion times S[row, row] added to its
    run's own terms (magnitude: in phase with it; phase: in quadrature)."""
    p = typed[(Axis.X, Axis.X)].coverage_probability
    rows = []
    for j in AXES:
        row = []
        s_jj = abs(complex(typed[(j, j)].sensitivity[i]))
        for o in AXES:
            ch = typed[(o, j)]
            z = complex(ch.sensitivity[i])
            size = abs(z)
            k_mag, k_ph = float(ch.coverage_factor[i]), float(ch.phase_coverage_factor[i])
            u_mag = size * float(ch.relative_expanded[i]) / k_mag if k_mag > 0 else math.nan
            u_ph = float(ch.phase_expanded_deg[i]) / k_ph if k_ph > 0 else math.nan
            if o != j:
                table_u = _table_terms(table, float(ch.frequency_hz[i]))
                own = (u_mag, float(ch.dof[i]))
                u_mag, k_mag = _combined([own, *((s_jj * u, d) for u, d in table_u)], p)
                quadrature = [(s_jj * u / size, d) for u, d in table_u] if size > 0 else []
                u_rad, k_ph = _combined([(math.radians(u_ph), own[1]), *quadrature], p)
                u_ph = math.degrees(u_rad) if size > 0 else math.nan
            row.append(
                MatrixEntry(
                    row=j,
                    column=o,
                    magnitude_mv_per_ms2=size,
                    magnitude_expanded=k_mag * u_mag,
                    magnitude_k=k_mag,
                    phase_deg=math.degrees(math.atan2(z.imag, z.real)),
                    phase_expanded_deg=k_ph * u_ph,
                    phase_k=k_ph,
                )
            )
        rows.append(tuple(row))
    return tuple(rows)


def _combined(parts: list[tuple[float, float]], p: float) -> tuple[float, float]:
    """(u, k) of independent (u_i, dof_i): root sum of squares, Welch-Satterthwaite, Student
    t at p; NaN when a part is not finite."""
    us = [u for u, _ in parts]
    if not all(math.isfinite(u) for u in us):
        return math.nan, math.nan
    u = math.hypot(*us)
    nu = welch_satterthwaite(us, [d for _, d in parts]) if u > 0 else math.inf
    return u, coverage_factor(nu, p)
