"""Measurement uncertainty of one calibration line (GUM; SPEC.md section 7).

Type A comes from the estimator (SPEC.md section 6). This module holds the type B budget,
combines both (JCGM 100:2008 "GUM" 5.1.2), finds the effective degrees of freedom
(Welch-Satterthwaite, GUM G.4.1) and the coverage factor (Student t, GUM G.3, G.6.4), and
compares the relative expanded uncertainty with the ISO 16063-21 suggested limits.

Units: magnitude values are relative (a fraction: 0.01 = 1 %), phase values are in degrees,
frequencies in Hz. Every result is in the unit of its inputs. Pure numpy/scipy, no I/O.
"""

from __future__ import annotations

import math
import numbers
import operator
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, fields
from enum import StrEnum
from typing import Any

import numpy as np

from dsp.annex_a import ComponentKind
from dsp.estimators import RULES
from dsp.quantiles import normal_quantile, t_quantile  # not scipy.special: issue 34

__all__ = [
    "Budget",
    "Combined",
    "Component",
    "Distribution",
    "Law",
    "Quantity",
    "Verdict",
    "combine",
    "coverage_factor",
    "iso_16063_21_limit",
    "iso_verdict",
    "seed_coverage_factor",
    "welch_satterthwaite",
]


class Distribution(StrEnum):
    """How a type B component's `value` is to be read (SPEC.md section 7)."""

    NORMAL = "normal"  # value is an expanded uncertainty U with coverage factor k
    RECTANGULAR = "rectangular"  # value is the half-width a
    TRIANGULAR = "triangular"  # value is the half-width a
    U_SHAPED = "u-shaped"  # value is the half-width a (arcsine distribution)
    STANDARD = "standard"  # value is already a standard uncertainty u


class Law(StrEnum):
    """How a component's value depends on frequency f (Hz); f0 = `law_frequency_hz`, n =
    `law_exponent` (issue 25 point 3: mounting and transverse motion grow with frequency,
    the skew's phase term is 360 f u(tau))."""

    CONSTANT = "constant"  # value at every f
    POWER_ABOVE = "power-above"  # value below f0, value (f/f0)^n above
    POWER_BELOW = "power-below"  # value above f0, value (f0/f)^n below (low-frequency terms)
    POWER = "power"  # value (f/f0)^n at every f


class Quantity(StrEnum):
    """What a value refers to: relative magnitude (fraction) or phase (degrees)."""

    MAGNITUDE = "magnitude"  # relative, a fraction: 0.01 = 1 %
    PHASE = "phase"  # degrees


class Verdict(StrEnum):
    """A line's expanded uncertainty against the ISO 16063-21 suggested limit."""

    WITHIN = "within"
    OVER = "over"
    NOT_APPLICABLE = "n/a"


# Divisor u = value / divisor for the distributions with a half-width a.
_DIVISORS: dict[Distribution, float] = {
    Distribution.RECTANGULAR: math.sqrt(3.0),  # GUM 4.3.7: u^2 = a^2/3
    Distribution.TRIANGULAR: math.sqrt(6.0),  # GUM 4.3.9: u^2 = a^2/6
    Distribution.U_SHAPED: math.sqrt(2.0),  # SPEC.md section 7: arcsine on [-a, a], u^2 = a^2/2
    Distribution.STANDARD: 1.0,  # GUM 4.3.1: the value already is u
}

_DOF_HELP = "a number > 0, null or 'inf'"


def _real(where: str, field: str, x: object) -> float:
    """`x` as a float; ValueError naming `field` if it is not a real number (bool refused)."""
    if isinstance(x, bool) or not isinstance(x, numbers.Real):
        raise ValueError(f"{where}: {field} must be a number, got {x!r}")
    return float(x)


def _enum(where: str, field: str, enum: type[StrEnum], x: object) -> Any:
    """`x` as a member of `enum` (case-insensitive); ValueError naming `field` otherwise."""
    key = x.strip().lower() if isinstance(x, str) else x
    try:
        return enum(key)  # type: ignore[arg-type]  # a non-str is refused by the enum
    except ValueError:
        choices = ", ".join(repr(m.value) for m in enum)
        raise ValueError(f"{where}: {field} must be one of {choices}, got {x!r}") from None


def _check_frequency(where: str, frequency_hz: float) -> float:
    f = _real(where, "frequency_hz", frequency_hz)
    if math.isnan(f):
        raise ValueError(f"{where}: frequency_hz must not be NaN")
    return f


@dataclass(frozen=True)
class Component:
    """One named type B component of the budget (SPEC.md section 7).

    `value` is read according to `distribution`: half-width a (rectangular, triangular,
    U-shaped), expanded uncertainty U with `coverage_factor` k (normal) or standard
    uncertainty u (standard). Unit: relative (fraction) for magnitude, degrees for phase.
    `dof` are its degrees of freedom (GUM G.4.2; default infinite, i.e. exactly known).
    The component applies from `min_frequency_hz` to `max_frequency_hz` inclusive (Hz;
    None = unbounded). `law` (with `law_frequency_hz` f0 and `law_exponent` n) scales the
    value with frequency; `kind` names the ISO 16063-21 Annex A component(s) it states
    (dsp.annex_a; empty for terms the procedure measures itself).
    """

    name: str
    value: float
    distribution: Distribution = Distribution.RECTANGULAR
    coverage_factor: float = 2.0
    dof: float = math.inf
    quantity: Quantity = Quantity.MAGNITUDE
    min_frequency_hz: float | None = None
    max_frequency_hz: float | None = None
    note: str = ""
    kind: tuple[ComponentKind, ...] = ()
    law: Law = Law.CONSTANT
    law_frequency_hz: float | None = None
    law_exponent: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError(f"component {self.name!r}: name must be a non-empty string")
        where = f"component {self.name!r}"
        set_ = object.__setattr__

        value = _real(where, "value", self.value)
        if not math.isfinite(value):
            raise ValueError(f"{where}: value must be finite, got {self.value!r}")
        if value < 0:
            raise ValueError(f"{where}: value must be >= 0, got {self.value!r}")
        set_(self, "value", value)

        set_(self, "distribution", _enum(where, "distribution", Distribution, self.distribution))
        set_(self, "quantity", _enum(where, "quantity", Quantity, self.quantity))

        k = _real(where, "coverage_factor", self.coverage_factor)
        if not (math.isfinite(k) and k > 0):
            raise ValueError(f"{where}: coverage_factor must be finite and > 0, got {k!r}")
        set_(self, "coverage_factor", k)

        dof = _real(where, "dof", self.dof)
        if not dof > 0:  # also refuses NaN
            raise ValueError(f"{where}: dof must be > 0 (inf allowed), got {self.dof!r}")
        set_(self, "dof", dof)

        for field in ("min_frequency_hz", "max_frequency_hz"):
            raw = getattr(self, field)
            if raw is None:
                continue
            f = _real(where, field, raw)
            if not (math.isfinite(f) and f >= 0):
                raise ValueError(f"{where}: {field} must be finite and >= 0 Hz, got {raw!r}")
            set_(self, field, f)
        lo, hi = self.min_frequency_hz, self.max_frequency_hz
        if lo is not None and hi is not None and lo > hi:
            raise ValueError(
                f"{where}: min_frequency_hz must be <= max_frequency_hz, got {lo!r} > {hi!r}"
            )

        if not isinstance(self.note, str):
            raise ValueError(f"{where}: note must be a string, got {self.note!r}")
        self._check_kind_and_law(where)

    def _check_kind_and_law(self, where: str) -> None:
        """Validate and normalise `kind` (a name or a list of names) and the law fields."""
        set_ = object.__setattr__
        raw = self.kind
        kinds = [raw] if isinstance(raw, str) else raw
        if not isinstance(kinds, list | tuple):
            raise ValueError(f"{where}: kind must be a name or a list of names, got {raw!r}")
        set_(self, "kind", tuple(_enum(where, "kind", ComponentKind, k) for k in kinds))
        law = _enum(where, "law", Law, self.law)
        set_(self, "law", law)
        n = _real(where, "law_exponent", self.law_exponent)
        if not (math.isfinite(n) and 0 <= n <= 4):
            raise ValueError(f"{where}: law_exponent must be between 0 and 4, got {n!r}")
        set_(self, "law_exponent", n)
        f0 = self.law_frequency_hz
        if law is Law.CONSTANT:
            if f0 is not None or n != 0:
                raise ValueError(f"{where}: law_frequency_hz/law_exponent need law 'power*'")
            return
        if f0 is None:
            raise ValueError(f"{where}: law {law.value!r} needs law_frequency_hz (f0, Hz)")
        f0 = _real(where, "law_frequency_hz", f0)
        if not (math.isfinite(f0) and f0 > 0):
            raise ValueError(f"{where}: law_frequency_hz must be finite and > 0 Hz, got {f0!r}")
        set_(self, "law_frequency_hz", f0)

    def scale_at(self, frequency_hz: float) -> float:
        """The law's factor at `frequency_hz` (Hz): 1, or (f/f0)^n (above f0 only for
        'power-above'), or (f0/f)^n below f0 for 'power-below'."""
        if self.law is Law.CONSTANT:
            return 1.0
        f = _check_frequency(f"component {self.name!r}", frequency_hz)
        assert self.law_frequency_hz is not None
        ratio = f / self.law_frequency_hz
        if self.law is Law.POWER_ABOVE and ratio <= 1.0:
            return 1.0
        if self.law is Law.POWER_BELOW:
            return 1.0 if ratio >= 1.0 else float(ratio**-self.law_exponent)
        return float(ratio**self.law_exponent)

    def standard_uncertainty_at(self, frequency_hz: float) -> float:
        """Standard uncertainty at `frequency_hz` (Hz): `standard_uncertainty` times the law's
        factor, in the component's unit."""
        return self.standard_uncertainty * self.scale_at(frequency_hz)

    @property
    def standard_uncertainty(self) -> float:
        """Standard uncertainty u, in the component's unit (relative or degrees).

        Rectangular a/sqrt(3) (GUM 4.3.7), triangular a/sqrt(6) (GUM 4.3.9), U-shaped
        a/sqrt(2) (SPEC.md section 7), normal U/k (GUM 4.3.3), standard u (GUM 4.3.1).
        """
        if self.distribution is Distribution.NORMAL:
            return self.value / self.coverage_factor
        return self.value / _DIVISORS[self.distribution]

    def applies_at(self, frequency_hz: float) -> bool:
        """Whether the component applies at `frequency_hz` (Hz; range inclusive)."""
        f = _check_frequency(f"component {self.name!r}", frequency_hz)
        if self.min_frequency_hz is not None and f < self.min_frequency_hz:
            return False
        return self.max_frequency_hz is None or f <= self.max_frequency_hz

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict of all fields; infinite dof is written as None."""
        return {
            "name": self.name,
            "value": self.value,
            "distribution": self.distribution.value,
            "coverage_factor": self.coverage_factor,
            "dof": None if math.isinf(self.dof) else self.dof,
            "quantity": self.quantity.value,
            "min_frequency_hz": self.min_frequency_hz,
            "max_frequency_hz": self.max_frequency_hz,
            "note": self.note,
            **self._law_dict(),
        }

    def _law_dict(self) -> dict[str, Any]:
        """kind and law keys, only when set (records without them stay as they were)."""
        out: dict[str, Any] = {}
        if self.kind:
            out["kind"] = [k.value for k in self.kind]
        if self.law is not Law.CONSTANT:
            out["law"] = self.law.value
            out["law_frequency_hz"] = self.law_frequency_hz
            out["law_exponent"] = self.law_exponent
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Component:
        """Component from a dict as written by `to_dict` (or a configuration file).

        `name` and `value` are required; `dof` may be a number, None or "inf" (infinite).
        Raises ValueError naming the missing, unknown or bad key and the component.
        """
        if not isinstance(d, Mapping):
            raise ValueError(f"component: expected a mapping of keys to values, got {d!r}")
        name = d.get("name")
        where = f"component {name!r}" if isinstance(name, str) and name else "component <unnamed>"
        known = [f.name for f in fields(cls)]
        for key in d:
            if key not in known:
                raise ValueError(f"{where}: unknown key {key!r} (known keys: {', '.join(known)})")
        for key in ("name", "value"):
            if key not in d:
                raise ValueError(f"{where}: missing key {key!r}")
        kwargs = dict(d)
        if "dof" in kwargs:
            dof = kwargs["dof"]
            if dof is None:
                kwargs["dof"] = math.inf
            elif isinstance(dof, str):
                if dof.strip().lower() not in ("inf", "infinity"):
                    raise ValueError(f"{where}: dof must be {_DOF_HELP}, got {dof!r}")
                kwargs["dof"] = math.inf
        return cls(**kwargs)


@dataclass(frozen=True)
class Budget:
    """The type B budget of a stand: named components (SPEC.md section 7)."""

    components: tuple[Component, ...] = ()

    def __post_init__(self) -> None:
        comps = tuple(self.components)
        for i, c in enumerate(comps, start=1):
            if not isinstance(c, Component):
                raise TypeError(f"budget entry {i}: expected a Component, got {c!r}")
        object.__setattr__(self, "components", comps)

    def at(self, frequency_hz: float, quantity: Quantity) -> tuple[Component, ...]:
        """Components of `quantity` that apply at `frequency_hz` (Hz)."""
        q = _enum("budget", "quantity", Quantity, quantity)
        return tuple(c for c in self.components if c.quantity is q and c.applies_at(frequency_hz))

    def type_b(self, frequency_hz: float, quantity: Quantity) -> tuple[float, float]:
        """(combined type B standard uncertainty, its Welch-Satterthwaite dof) at a frequency.

        u_B = sqrt(sum u_Bi^2) (GUM 5.1.2 eq. 10 with unit sensitivity coefficients;
        SPEC.md section 7), nu_B by GUM G.4.1 eq. G.2b. Unit: relative (magnitude) or
        degrees (phase). No applying component gives (0.0, inf).
        """
        comps = self.at(frequency_hz, quantity)
        us = [c.standard_uncertainty_at(frequency_hz) for c in comps]
        u_b = math.hypot(*us)  # sqrt(sum u_i^2) without under- or overflow
        return u_b, welch_satterthwaite(us, [c.dof for c in comps])

    def to_list(self) -> list[dict[str, Any]]:
        """JSON-safe list of component dicts (see `Component.to_dict`)."""
        return [c.to_dict() for c in self.components]

    @classmethod
    def from_list(cls, entries: Iterable[Mapping[str, Any]]) -> Budget:
        """Budget from a list of component dicts; errors name the entry (1-based) and key."""
        from dsp.budget_table import expand_table

        items = list(entries)
        comps = []
        for i, entry in enumerate(items, start=1):
            try:  # a `table` entry: one component per row (dsp.budget_table)
                comps += [Component.from_dict(e) for e in expand_table(entry)]
            except (ValueError, TypeError) as exc:
                raise ValueError(f"budget entry {i} of {len(items)}: {exc}") from exc
        return cls(tuple(comps))

    @classmethod
    def seed_rectangular(cls, mpes: Mapping[str, float]) -> Budget:
        """Seed eq. 18/19: relative maximum permissible errors delta_gi, rectangular.

        `mpes` maps a name to its relative MPE (fraction). The budget's `type_b` at any
        frequency is then sqrt(sum delta_gi^2)/sqrt(3) (seed eq. 19; SPEC.md section 7).
        """
        return cls(
            tuple(
                Component(
                    name=name,
                    value=mpe,
                    distribution=Distribution.RECTANGULAR,
                    note="maximum permissible error (seed eq. 18/19)",
                )
                for name, mpe in mpes.items()
            )
        )


def welch_satterthwaite(standard_uncertainties: Sequence[float], dofs: Sequence[float]) -> float:
    """Effective degrees of freedom nu_eff = u_c^4 / sum(u_i^4 / nu_i) (GUM G.4.1 eq. G.2b).

    u_c^2 = sum u_i^2 (unit sensitivity coefficients). Components with infinite dof
    contribute 0 to the denominator; all infinite or a zero total gives inf. A NaN
    uncertainty gives NaN. The u_i share one unit (any); dofs are > 0 (inf allowed).
    """
    u = np.asarray(standard_uncertainties, dtype=float)
    nu = np.asarray(dofs, dtype=float)
    if u.ndim != 1 or u.shape != nu.shape:
        raise ValueError(
            "welch_satterthwaite: standard_uncertainties and dofs must be 1-D and of equal "
            f"length, got shapes {u.shape} and {nu.shape}"
        )
    if np.isnan(u).any():
        return math.nan
    if not (np.isfinite(u).all() and (u >= 0).all()):
        raise ValueError(f"welch_satterthwaite: uncertainties must be finite and >= 0, got {u}")
    if not (nu > 0).all():  # also refuses NaN
        raise ValueError(f"welch_satterthwaite: dofs must be > 0 (inf allowed), got {nu}")
    scale = float(u.max(initial=0.0))
    if scale == 0.0:
        return math.inf
    r = u / scale  # scale-free, so u_i^4 neither underflows nor overflows
    finite = np.isfinite(nu)
    denominator = float(np.sum(r[finite] ** 4 / nu[finite]))
    if denominator == 0.0:
        return math.inf
    return float(np.sum(r**2) ** 2 / denominator)


def coverage_factor(dof: float, probability: float = 0.9545) -> float:
    """Coverage factor k = t_{(1+p)/2}(nu) of Student's t (GUM G.3.2, G.6.4, Table G.2).

    Infinite `dof` gives the normal quantile (GUM G.2.3). `probability` p is the coverage
    probability as a fraction (default 0.9545, so k -> 2 for large nu; SPEC.md section 7).
    """
    p = _real("coverage_factor", "probability", probability)
    if not 0.0 < p < 1.0:
        raise ValueError(f"coverage_factor: probability must be in (0, 1), got {probability!r}")
    nu = _real("coverage_factor", "dof", dof)
    if not nu > 0:  # also refuses NaN
        raise ValueError(f"coverage_factor: dof must be > 0 (inf allowed), got {dof!r}")
    q = (1.0 + p) / 2.0
    if math.isinf(nu):
        return normal_quantile(q)
    return t_quantile(nu, q)


def seed_coverage_factor(periods: int) -> float:
    """Seed rule (SPEC.md section 7): L < 10 periods -> t at 95 % with nu = L - 1, else 2.

    `periods` is L, the number of periods (segments) averaged; L >= 2.
    """
    if isinstance(periods, bool):
        raise ValueError(f"seed_coverage_factor: periods must be an integer, got {periods!r}")
    try:
        n = operator.index(periods)
    except TypeError:
        raise ValueError(
            f"seed_coverage_factor: periods must be an integer, got {periods!r}"
        ) from None
    if n < 2:
        raise ValueError(f"seed_coverage_factor: periods must be >= 2, got {n}")
    if n < 10:
        return coverage_factor(n - 1, 0.95)
    return 2.0


def seed_coverage_probability(periods: int) -> float:
    """The coverage probability the seed's rule gives with L = `periods`: 0.95 for L < 10 (t at
    95 % with L - 1 degrees of freedom), else 0.9545 (k = 2 of a normal distribution, GUM G.1.3;
    not 95 %: the seed's Table 1 states "95 %" for it, SPEC.md section 7)."""
    return 0.95 if seed_coverage_factor(periods) != 2.0 else 0.9545


@dataclass(frozen=True)
class Combined:
    """A line's uncertainty statement (SPEC.md section 7; GUM 5.1.2, G.4.1, 6.2.1).

    Uncertainties share the inputs' unit: relative (fraction) for magnitude, degrees for
    phase. `coverage_probability` is a fraction (0.9545 = 95.45 %).
    """

    type_a: float  # u_A
    type_a_dof: float  # nu_A
    type_b: float  # u_B = sqrt(sum u_Bi^2)
    standard: float  # u_c
    dof: float  # nu_eff
    coverage_factor: float  # k
    coverage_probability: float  # p
    expanded: float  # U = k u_c


_RULES = RULES  # the one list: dsp.estimators


def combine(
    type_a: float,
    type_a_dof: float,
    budget: Budget,
    frequency_hz: float,
    quantity: Quantity = Quantity.MAGNITUDE,
    *,
    probability: float = 0.9545,
    rule: str = "gum",
    periods: int | None = None,
) -> Combined:
    """Combine type A and the budget's type B at one line (SPEC.md section 7).

    u_c = sqrt(u_A^2 + sum u_Bi^2) (GUM 5.1.2 eq. 10, unit sensitivity coefficients);
    nu_eff by Welch-Satterthwaite over u_A and every applying u_Bi (GUM G.4.1 eq. G.2b);
    k = coverage_factor(nu_eff, probability) for rule "gum" (GUM G.6.4), or the seed's rule
    from `periods` for rule "seed" (then p is what that k gives: 0.95 for L < 10, 0.9545 for
    k = 2 of a normal distribution, L >= 10: seed_coverage_probability); U = k u_c (GUM 6.2.1
    eq. 18).
    `type_a` is in the unit of `quantity` (relative or degrees). A NaN `type_a` (e.g. one
    period only, whatever its dof) gives NaN u_c, nu_eff and U (and k under rule "gum").
    """
    if rule not in _RULES:
        raise ValueError(f"combine: rule must be one of {_RULES}, got {rule!r}")
    p = _real("combine", "probability", probability)
    if not 0.0 < p < 1.0:
        raise ValueError(f"combine: probability must be in (0, 1), got {probability!r}")
    if rule == "seed" and periods is None:
        raise ValueError("combine: rule 'seed' needs periods (the number of periods L)")
    if not isinstance(budget, Budget):
        raise TypeError(f"combine: budget must be a Budget, got {budget!r}")
    q = _enum("combine", "quantity", Quantity, quantity)
    u_a = _real("combine", "type_a", type_a)
    nu_a = _real("combine", "type_a_dof", type_a_dof)
    a_known = not math.isnan(u_a)
    if a_known:
        if not (math.isfinite(u_a) and u_a >= 0):
            raise ValueError(f"combine: type_a must be finite and >= 0 (or NaN), got {type_a!r}")
        if not nu_a > 0:
            raise ValueError(f"combine: type_a_dof must be > 0 (inf allowed), got {type_a_dof!r}")

    comps = budget.at(frequency_hz, q)
    u_bi = [c.standard_uncertainty_at(frequency_hz) for c in comps]
    u_b = math.hypot(*u_bi)  # sqrt(sum u_Bi^2) without under- or overflow
    if a_known:
        u_c = math.hypot(u_a, *u_bi)
        nu_eff = welch_satterthwaite([u_a, *u_bi], [nu_a, *(c.dof for c in comps)])
    else:
        u_c = nu_eff = math.nan

    if rule == "seed":
        assert periods is not None
        k, p_reported = seed_coverage_factor(periods), seed_coverage_probability(periods)
    else:
        k = math.nan if math.isnan(nu_eff) else coverage_factor(nu_eff, p)
        p_reported = p
    return Combined(
        type_a=u_a,
        type_a_dof=nu_a,
        type_b=u_b,
        standard=u_c,
        dof=nu_eff,
        coverage_factor=k,
        coverage_probability=p_reported,
        expanded=k * u_c,
    )


# ISO 16063-21 suggested limits of the relative expanded uncertainty (SPEC.md section 7):
# (lower bound Hz exclusive, upper bound Hz inclusive, limit); the first band also
# includes its lower bound, 0.4 Hz.
_ISO_16063_21_BANDS: tuple[tuple[float, float, float], ...] = (
    (0.4, 1000.0, 0.02),
    (1000.0, 2000.0, 0.04),
    (2000.0, 10000.0, 0.06),
)


def iso_16063_21_limit(frequency_hz: float) -> float | None:
    """ISO 16063-21 suggested limit of the relative expanded uncertainty at a frequency.

    0.02 for 0.4 Hz <= f <= 1 kHz, 0.04 for 1 kHz < f <= 2 kHz, 0.06 for 2 kHz < f <= 10 kHz
    (fractions; SPEC.md section 7); None outside 0.4 Hz to 10 kHz.
    """
    f = _check_frequency("iso_16063_21_limit", frequency_hz)
    if f == _ISO_16063_21_BANDS[0][0]:
        return _ISO_16063_21_BANDS[0][2]
    for lo, hi, limit in _ISO_16063_21_BANDS:
        if lo < f <= hi:
            return limit
    return None


def iso_verdict(frequency_hz: float, relative_expanded_uncertainty: float) -> Verdict:
    """WITHIN if U_rel <= the ISO 16063-21 limit at the frequency, OVER if above.

    `relative_expanded_uncertainty` is a fraction (0.02 = 2 %). NOT_APPLICABLE outside
    0.4 Hz to 10 kHz. A NaN uncertainty (not determined) is OVER: an unknown uncertainty
    cannot be shown to meet the limit (SPEC.md section 7).
    """
    limit = iso_16063_21_limit(frequency_hz)
    if limit is None:
        return Verdict.NOT_APPLICABLE
    u = _real("iso_verdict", "relative_expanded_uncertainty", relative_expanded_uncertainty)
    if math.isnan(u):
        return Verdict.OVER
    if u < 0:
        raise ValueError(f"iso_verdict: relative_expanded_uncertainty must be >= 0, got {u!r}")
    return Verdict.WITHIN if u <= limit else Verdict.OVER
