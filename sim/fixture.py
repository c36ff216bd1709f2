"""The simulated fixture block of a several-DUT run: rocking, bending, crosstalk (issue 36 point 2).

A fixture block is bolted to the exciter's armature; the reference accelerometer sits on the
block's axis (back-to-back), the DUTs at named positions around it. A real block does not move
as one rigid piston: it rocks about the two horizontal axes, and a DUT off the axis then sees
an axial acceleration that is not the reference's. ISO 16063-21:2003 Annex A lists this as the
"relative motion between the reference and the DUT" component; it grows with the distance from
the axis and with frequency towards the armature's rocking modes (G. P. Ripper, G. A. Garcia,
R. S. Dias, "Primary accelerometer calibration problems due to vibration exciters", XVIII IMEKO
World Congress, Rio de Janeiro, 2006: the exciters' cross motion, transverse and rocking, at
high frequency; PTB's multi-component exciter work, working group 1.71, measures the rotational
components that make it). This module is the simulator's truth of it, never the budget: the
stand file states the budget's terms (`relative_motion`, `crosstalk_db`), and
bench/fixture_terms.py checks that they bound what this model does.

Kinematics (x, y horizontal, z the exciter's axis; the reference at the origin). The block
rotates by small angles theta_x, theta_y about the x and y axes. A point at r = (x, y, z) on a
rigid body turning with angular acceleration alpha = (alpha_x, alpha_y, 0) sees, besides the
axis' translation, alpha x r, whose axial component is

    (alpha x r)_z = alpha_x y - alpha_y x

(the centripetal term is second order in the small angles and dropped). With
x = d cos(phi), y = d sin(phi) (distance d, m; azimuth phi from the x axis):

    a_z(d, phi) = a (1 + d (theta_x'' sin(phi) - theta_y'' cos(phi)) / a)

where a is the reference axis' axial acceleration and theta'' the angular accelerations.

Rocking (one degree of freedom per horizontal axis). The block with its DUTs has mass m, its
centre of mass off the axis by e = (e_x, e_y) (the eccentricity), moment of inertia
I = m rho^2 about each horizontal axis (rho the radius of gyration, m), on the armature's
rotational stiffness k (rocking frequency w0 = sqrt(k / I)) with damping giving quality factor
Q. The axial acceleration a puts the d'Alembert force -m a at e, a moment
M = r x F: M_x = -m e_y a, M_y = +m e_x a. With theta'' = -w^2 theta (sinusoidal, angular
frequency w):

    I theta_x'' + c theta_x' + k theta_x = -m e_y a
    =>  theta_x'' / a = (e_y / rho_x^2) H_x(w),   theta_y'' / a = -(e_x / rho_y^2) H_y(w),
    H(w) = w^2 / (w0^2 - w^2 + j w w0 / Q)

so that, with the eccentricity at azimuth phi_e (e_x = e cos phi_e, e_y = e sin phi_e),

    ratio(d, phi) = 1 + d e (sin(phi) sin(phi_e) H_x / rho_x^2 + cos(phi) cos(phi_e) H_y / rho_y^2)

Well below both modes H ~ (f / f0)^2: the relative motion grows as f^2 and linearly with d; at
a mode H = -jQ, so |ratio - 1| peaks near d e Q / rho^2 times the azimuths' projection (the
sin or cos products above); opposite azimuths give opposite signs; the side
of the eccentric mass moves more below the modes (it lags, then overshoots: in phase with the
displacement). A stiffness asymmetry of the armature's flexures couples too, with a moment
k_z e_k z = k_z e_k a / w^2 that falls as 1/f^2: it matters near the suspension's own
resonance (about 150 Hz on the simulated exciter, well under the rocking modes) and is left out.

Bending (optional; `bending_hz`). The block's mounting face has a first axisymmetric mode (an
"umbrella" mode of a plate held at its centre stud), excited by the axial inertia load itself:
the face at d deflects relative to the centre as (d / R)^2 (the mode shape of a uniformly loaded
plate near its centre, R the block's radius), so

    ratio += beta (d / R)^2 w^2 / (wb^2 - w^2 + j w wb / Qb)

with beta the mode's participation (the quasi-static relative deflection's factor). Its effect
also grows as f^2 but as d^2 and without azimuth; the reference on the axis (d = 0) is untouched.

Crosstalk (capacitive coupling between the input channels' cables and the multiplexer): a flat
part (a shared ground's resistance) and a capacitive part j w R C that grows 20 dB per decade.
Stated as the total magnitude `crosstalk_db` at `crosstalk_reference_hz` and the flat part
`crosstalk_flat_db`: C[i, j] = g_flat + j g_cap f / f_ref (i != j), with
g_flat^2 + g_cap^2 = 10^(crosstalk_db / 10); C[i, i] = 1. Every pair couples alike (a
conservative multiplexer: the budget's term is stated per other channel).

Mountings (optional; `mounting_offset_mm`, `rocking_scatter`, `crosstalk_scatter`). A lab's
block is not the same from batch to batch: it is taken off the armature to mount the DUTs and
bolted on again. Three things change with it, drawn per run from the run's seed (`mounted`):
- the centre of mass. The table's eccentricity is the block's with its DUTs' centres of mass
  on their studs; a mounted DUT's centre of mass (its side connector, the cable's first metres
  up to the clamp) is off its stud by `mounting_offset_mm`, at the azimuth where the thread
  stops at the mounting torque: uniform over the circle, one per DUT. The moment of each DUT
  (its mass times that offset) adds to the block's; over the total mass (block + DUTs) it is
  the run's eccentricity, magnitude and azimuth. A sum of a few fixed-length vectors at random
  angles: neither normal nor known to the analysis.
- the rocking stiffness: the contact of the block's base on the armature (surface condition,
  torque of the centre bolt) scales it by exp(rocking_scatter Z), Z standard normal; both
  rocking frequencies by its square root (the inertia is the same).
- the cables' routing: the capacitive crosstalk's part by exp(crosstalk_scatter Z).
The stated terms a lab derives from such mountings: `characterised_terms` (the lab's own
mountings, never the runs': another seed).

Units: frequencies Hz, distances m (mm in the table), angles degrees, ratios dimensionless.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hardware.errors import InputRefused

TABLE = "simulation.fixture"
RATIO_CACHE = 64  # motion ratios kept (position x frequency grid)
# key: (required, meaning) of [simulation.fixture]
KEYS: dict[str, tuple[bool, str]] = {
    "rocking_hz": (True, "rocking frequency, Hz: one number or [about x, about y]"),
    "rocking_q": (True, "rocking modes' quality factor: one number or [x, y]"),
    "eccentricity_mm": (True, "centre of mass (block + DUTs) off the axis, mm"),
    "eccentricity_azimuth_deg": (False, "azimuth of that offset from the x axis, degrees"),
    "gyration_radius_mm": (True, "radius of gyration about a horizontal axis, mm: one or [x, y]"),
    "bending_hz": (False, "first axisymmetric bending mode of the mounting face, Hz"),
    "bending_q": (False, "its quality factor"),
    "bending_participation": (False, "its quasi-static relative deflection factor beta"),
    "block_radius_mm": (False, "the block's radius R, mm (bending's mode shape (d/R)^2)"),
    "crosstalk_db": (True, "channel-to-channel coupling at crosstalk_reference_hz, dB"),
    "crosstalk_flat_db": (True, "its frequency-independent part, dB (below crosstalk_db)"),
    "crosstalk_reference_hz": (True, "the frequency crosstalk_db holds at, Hz"),
    "mounting_offset_mm": (False, "a mounted DUT's centre of mass off its stud's axis, mm"),
    "rocking_scatter": (False, "log-sd of the rocking stiffness from mounting to mounting"),
    "crosstalk_scatter": (False, "log-sd of the capacitive crosstalk from mounting to mounting"),
}


@dataclass(frozen=True)
class PositionGeometry:
    """Where a DUT sits on the block: its name, distance from the reference axis (m) and
    azimuth from the block's x axis (degrees)."""

    name: str
    distance_m: float
    azimuth_deg: float = 0.0


@dataclass(frozen=True)
class MountingScatter:
    """How one mounting of the block with its DUTs differs from the next (module docstring,
    "Mountings"): a DUT's centre of mass off its stud (m), the rocking stiffness' and the
    capacitive crosstalk's log standard deviations (dimensionless)."""

    mounting_offset_m: float = 0.0
    rocking_scatter: float = 0.0
    crosstalk_scatter: float = 0.0


@dataclass(frozen=True)
class Mode:
    """A single-degree-of-freedom mode: frequency (Hz) and quality factor."""

    frequency_hz: float
    q: float

    def response(self, frequency_hz: np.ndarray) -> np.ndarray:
        """H = w^2 / (w0^2 - w^2 + j w w0 / Q), complex, dimensionless (the angular or
        relative acceleration per unit of the driving acceleration, before the coupling)."""
        f = np.asarray(frequency_hz, dtype=np.float64)
        f0 = self.frequency_hz
        return f**2 / (f0**2 - f**2 + 1j * f * f0 / self.q)


@dataclass(frozen=True)
class FixtureModel:
    """The fixture's physics (module docstring): rocking about x and y, an optional bending
    mode, crosstalk. Satisfies sim.fixture_rigid.FixtureMotion structurally."""

    rocking_x: Mode  # about the x axis (excited by e_y)
    rocking_y: Mode  # about the y axis (excited by e_x)
    eccentricity_m: float
    eccentricity_azimuth_deg: float
    gyration_radius_m: tuple[float, float]  # (about x, about y)
    crosstalk_db: float
    crosstalk_flat_db: float
    crosstalk_reference_hz: float
    positions: Mapping[str, PositionGeometry] = field(default_factory=dict)
    bending: Mode | None = None
    bending_participation: float = 0.0
    block_radius_m: float = 0.05
    scatter: MountingScatter | None = None  # None: every mounting alike (no draw)
    # motion ratios already computed, by (position, the frequencies' digest): the simulated
    # stand asks for the same DFT bins every period
    _ratios: dict[tuple[str, bytes], np.ndarray] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    @classmethod
    def from_table(
        cls, table: Mapping[str, Any], positions: Sequence[PositionGeometry]
    ) -> FixtureModel:
        """The model of a stand file's [simulation.fixture] table for these positions;
        InputRefused naming the key (or position) that is unknown, missing or out of range."""
        unknown = sorted(set(table) - set(KEYS))
        if unknown:
            raise InputRefused(
                f"[{TABLE}] {unknown[0]}: unknown key; it may hold: {', '.join(KEYS)}"
            )
        missing = [k for k, (required, _) in KEYS.items() if required and k not in table]
        if missing:
            raise InputRefused(f"[{TABLE}] {missing[0]}: missing ({KEYS[missing[0]][1]})")
        rocking_hz = _pair(table, "rocking_hz", 1.0, 1e6)
        rocking_q = _pair(table, "rocking_q", 0.5, 1e4)
        gyration_mm = _pair(table, "gyration_radius_mm", 0.1, 1e4)
        bending = None
        participation = 0.0
        radius_mm = 50.0
        if "bending_hz" in table:
            bending = Mode(
                _number(table, "bending_hz", 1.0, 1e6), _number(table, "bending_q", 0.5, 1e4, 20.0)
            )
            participation = _number(table, "bending_participation", 0.0, 1.0, 0.0)
            radius_mm = _number(table, "block_radius_mm", 1.0, 1e4, 50.0)
        else:
            extra = [k for k in ("bending_q", "bending_participation") if k in table]
            if extra:
                raise InputRefused(f"[{TABLE}] {extra[0]}: given without bending_hz")
        total_db = _number(table, "crosstalk_db", -300.0, 0.0)
        flat_db = _number(table, "crosstalk_flat_db", -300.0, 0.0)
        if flat_db > total_db:
            raise InputRefused(
                f"[{TABLE}] crosstalk_flat_db: {flat_db:g} dB is above crosstalk_db "
                f"({total_db:g} dB), the total at crosstalk_reference_hz"
            )
        return cls(
            rocking_x=Mode(rocking_hz[0], rocking_q[0]),
            rocking_y=Mode(rocking_hz[1], rocking_q[1]),
            eccentricity_m=_number(table, "eccentricity_mm", 0.0, 1e3) * 1e-3,
            eccentricity_azimuth_deg=_number(table, "eccentricity_azimuth_deg", -360, 360, 0.0),
            gyration_radius_m=(gyration_mm[0] * 1e-3, gyration_mm[1] * 1e-3),
            crosstalk_db=total_db,
            crosstalk_flat_db=flat_db,
            crosstalk_reference_hz=_number(table, "crosstalk_reference_hz", 1e-3, 1e6),
            positions=_positions(positions),
            bending=bending,
            bending_participation=participation,
            block_radius_m=radius_mm * 1e-3,
            scatter=_scatter(table),
        )

    @classmethod
    def from_stand(cls, stand: Mapping[str, Any]) -> FixtureModel | None:
        """The model of a stand file's tables as read (its [simulation.fixture] with the
        [[fixture.position]] entries' name, distance_mm and azimuth_deg); None when it has no
        [simulation.fixture] (the rigid fixture then). InputRefused naming the table or key."""
        table = stand.get("simulation", {}).get("fixture")
        if table is None:
            return None
        fixture = stand.get("fixture")
        if not isinstance(table, Mapping) or not isinstance(fixture, Mapping):
            raise InputRefused(f"[{TABLE}]: a table, with the stand's [fixture] and its positions")
        positions = []
        for index, entry in enumerate(fixture.get("position", []), start=1):
            where = f"[[fixture.position]] {index}"
            if not isinstance(entry, Mapping) or not isinstance(entry.get("name"), str):
                raise InputRefused(f"{where}: needs a name")
            distance = _number(entry, "distance_mm", 0.0, 1e4, 0.0, where=where)
            azimuth = _number(entry, "azimuth_deg", -360.0, 360.0, 0.0, where=where)
            positions.append(PositionGeometry(entry["name"], distance * 1e-3, azimuth))
        return cls.from_table(table, positions)

    def mounted(
        self, seed: int, masses_g: Mapping[str, float], block_mass_g: float
    ) -> FixtureModel:
        """This fixture as mounted for one run (module docstring, "Mountings"): the
        eccentricity, the rocking frequencies and the capacitive crosstalk drawn from `seed`
        for the DUTs of `masses_g` (position -> g) on a block of `block_mass_g` (g); itself
        when the table states no mounting scatter."""
        if self.scatter is None:
            return self
        rng = np.random.default_rng(np.random.SeedSequence([int(seed), 36, 2]))
        return self._draw(rng, masses_g, block_mass_g)

    def _draw(
        self, rng: np.random.Generator, masses_g: Mapping[str, float], block_mass_g: float
    ) -> FixtureModel:
        """One mounting drawn with `rng` (see `mounted`)."""
        scatter = self.scatter
        assert scatter is not None
        unknown = sorted(set(masses_g) - set(self.positions))
        if unknown:
            self.geometry(unknown[0])  # InputRefused naming it
        phi_e = math.radians(self.eccentricity_azimuth_deg)
        total_g = block_mass_g + sum(masses_g.values())
        # g m: the nominal load's centre of mass (the table's eccentricity), then each DUT's
        moment = np.array([math.cos(phi_e), math.sin(phi_e)]) * self.eccentricity_m * total_g
        for position in sorted(masses_g):
            # where the stud's thread stops at the mounting torque: any azimuth alike
            turn = rng.uniform(0.0, 2.0 * math.pi)
            offset = scatter.mounting_offset_m * np.array([math.cos(turn), math.sin(turn)])
            moment += masses_g[position] * offset
        e = moment / total_g if total_g > 0 else moment * 0.0
        stiffness = math.exp(scatter.rocking_scatter * rng.standard_normal())
        coupling = math.exp(scatter.crosstalk_scatter * rng.standard_normal())
        total = 10.0 ** (self.crosstalk_db / 20.0)
        flat = 10.0 ** (self.crosstalk_flat_db / 20.0)
        capacitive = math.sqrt(max(total**2 - flat**2, 0.0)) * coupling
        return dataclasses.replace(
            self,
            rocking_x=Mode(self.rocking_x.frequency_hz * math.sqrt(stiffness), self.rocking_x.q),
            rocking_y=Mode(self.rocking_y.frequency_hz * math.sqrt(stiffness), self.rocking_y.q),
            eccentricity_m=float(np.hypot(*e)),
            eccentricity_azimuth_deg=math.degrees(math.atan2(e[1], e[0])),
            crosstalk_db=10.0 * math.log10(flat**2 + capacitive**2),
            scatter=None,
        )

    def geometry(self, position: str) -> PositionGeometry:
        """The position named `position`; InputRefused naming it and the known ones."""
        try:
            return self.positions[position]
        except KeyError:
            known = ", ".join(self.positions) or "none"
            raise InputRefused(f"fixture position {position!r}: unknown (known: {known})") from None

    def motion_ratio(self, position: str, frequency_hz: np.ndarray) -> np.ndarray:
        """Complex axial acceleration at `position` over that at the reference axis, at
        `frequency_hz` (Hz, any shape; the result has its shape)."""
        where = self.geometry(position)
        f = _frequencies(frequency_hz)
        key = (position, hashlib.blake2b(f.tobytes() + repr(f.shape).encode()).digest())
        known = self._ratios.get(key)
        if known is None:
            known = self._ratio(where, f)
            if len(self._ratios) >= RATIO_CACHE:
                self._ratios.clear()
            self._ratios[key] = known
        return known.copy()

    def _ratio(self, where: PositionGeometry, f: np.ndarray) -> np.ndarray:
        """motion_ratio's value, computed."""
        d = where.distance_m
        phi = math.radians(where.azimuth_deg)
        phi_e = math.radians(self.eccentricity_azimuth_deg)
        rho_x, rho_y = self.gyration_radius_m
        e = self.eccentricity_m
        ratio = np.ones(f.shape, dtype=np.complex128)
        if d == 0.0:
            return ratio  # on the axis: rocking and bending move it not at all
        about_x = math.sin(phi) * math.sin(phi_e) / rho_x**2
        about_y = math.cos(phi) * math.cos(phi_e) / rho_y**2
        if about_x:
            ratio += d * e * about_x * self.rocking_x.response(f)
        if about_y:
            ratio += d * e * about_y * self.rocking_y.response(f)
        if self.bending is not None and self.bending_participation:
            shape = (d / self.block_radius_m) ** 2
            ratio += self.bending_participation * shape * self.bending.response(f)
        return ratio

    def crosstalk(self, frequency_hz: np.ndarray, channels: Sequence[str]) -> np.ndarray:
        """Complex (F, n, n) mixing of the n input channels' voltages at the F frequencies
        (Hz): v_out = C @ v_in, C[:, i, i] = 1, every other entry the coupling of the module
        docstring (|C| = 10^(crosstalk_db / 20) at crosstalk_reference_hz)."""
        f = _frequencies(frequency_hz).reshape(-1)
        names = list(channels)
        if len(set(names)) != len(names):
            twice = next(n for n in names if names.count(n) > 1)
            raise InputRefused(f"crosstalk: channel {twice!r} named twice")
        n = len(names)
        total = 10.0 ** (self.crosstalk_db / 20.0)
        flat = 10.0 ** (self.crosstalk_flat_db / 20.0)
        capacitive = math.sqrt(max(total**2 - flat**2, 0.0))
        coupling = flat + 1j * capacitive * f / self.crosstalk_reference_hz
        mixing = np.broadcast_to(coupling[:, None, None], (f.size, n, n)).copy()
        index = np.arange(n)
        mixing[:, index, index] = 1.0
        return mixing


def relative_motion_truth(
    model: FixtureModel, frequency_hz: Sequence[float] | np.ndarray
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per position: |ratio - 1| (percent) and the ratio's phase (degrees) at the frequencies
    (Hz): what the stated `relative_motion` and `relative_motion_phase_deg` must bound."""
    f = np.asarray(frequency_hz, dtype=np.float64)
    out = {}
    for name in model.positions:
        ratio = model.motion_ratio(name, f)
        out[name] = (100.0 * np.abs(ratio - 1.0), np.degrees(np.angle(ratio)))
    return out


@dataclass(frozen=True)
class StatedTerm:
    """A position's stated relative motion: rows (Hz, percent) and (Hz, degrees), the form of
    the stand file's `relative_motion` and `relative_motion_phase_deg`."""

    position: str
    magnitude: tuple[tuple[float, float], ...]
    phase: tuple[tuple[float, float], ...]


def stated_terms(
    model: FixtureModel,
    nodes_hz: Sequence[float],
    *,
    margin: float = 1.5,
    floor_percent: float = 0.005,
    floor_deg: float = 0.003,
) -> list[StatedTerm]:
    """The terms a lab would state for this fixture: per position, rows at the nodes (Hz) and
    at the rocking and bending modes between them, each `margin` times the truth
    (relative_motion_truth) there, never below the floors (percent, degrees: what the lab's
    measurement of its block could resolve); then, interval by interval, both ends raised
    until the log-log interpolation (`interpolated`) is `margin` times the truth on a dense
    grid between them (a resonance's top is concave in log-log: the chord would cut it)."""
    nodes = sorted(float(f) for f in nodes_hz)
    if len(nodes) < 2 or nodes[0] <= 0:
        raise ValueError("stated_terms: needs at least two frequencies > 0 Hz")
    if margin < 1.0:
        raise ValueError(f"stated_terms: margin {margin:g} below 1 cannot bound the truth")
    modes = [model.rocking_x, model.rocking_y, *([model.bending] if model.bending else [])]
    inside = [m.frequency_hz for m in modes if nodes[0] < m.frequency_hz < nodes[-1]]
    f = np.asarray(sorted(set(nodes) | set(inside)))
    truth = relative_motion_truth(model, f)
    grids = [np.geomspace(lo, hi, 256) for lo, hi in itertools.pairwise(f)]
    dense = [relative_motion_truth(model, grid) for grid in grids]
    terms = []
    for name in model.positions:
        magnitude = np.maximum(margin * truth[name][0], floor_percent)
        phase = np.maximum(margin * np.abs(truth[name][1]), floor_deg)
        for which, values in ((0, magnitude), (1, phase)):
            for i, grid in enumerate(grids):
                rows = [(f[i], values[i]), (f[i + 1], values[i + 1])]
                wanted = margin * np.abs(dense[i][name][which])
                short = float(np.max(wanted / interpolated(rows, grid)))
                if short > 1.0:
                    values[i : i + 2] *= short * (1 + 1e-9)
        terms.append(
            StatedTerm(
                name,
                tuple((float(x), _round_up(float(v))) for x, v in zip(f, magnitude, strict=True)),
                tuple((float(x), _round_up(float(v))) for x, v in zip(f, phase, strict=True)),
            )
        )
    return terms


LAB_SEED = 16_063  # the lab's characterisation mountings (not a run's seed: runs use [seed, 36, 2])


def characterised_terms(
    model: FixtureModel,
    masses_g: Mapping[str, float],
    block_mass_g: float,
    nodes_hz: Sequence[float],
    *,
    mountings: int = 50,
    margin: float = 1.0,
    seed: int = LAB_SEED,
    floor_percent: float = 0.005,
    floor_deg: float = 0.003,
) -> tuple[list[StatedTerm], float]:
    """What a lab states for a fixture whose mounting scatters (`model.scatter`): it mounts the
    block `mountings` times with the DUTs of `masses_g` (g per position) and measures each
    position's motion against the axis at the nodes (Hz; its calibration lines). Per position
    and node the standard uncertainty is the root mean square over the mountings (about zero:
    the lab does not correct the mean) of the magnitude's deviation (percent, |ratio| - 1) and
    of the phase (degrees), times `margin`, rounded up to two digits, never below the floors
    (its resolution); the crosstalk the root mean square of the largest coupling over the nodes,
    in dB rounded up to a whole dB. Returns (terms, crosstalk_db)."""
    if mountings < 2:
        raise ValueError("characterised_terms: needs at least two mountings")
    if model.scatter is None:
        raise ValueError("characterised_terms: the fixture states no mounting scatter")
    f = np.asarray(sorted(float(x) for x in nodes_hz), dtype=np.float64)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 36, 3]))
    names = list(model.positions)
    magnitude = np.zeros((len(names), f.size))
    phase = np.zeros((len(names), f.size))
    coupling = np.zeros(mountings)
    channels = ["reference", *(f"dut.{n}" for n in names)]
    off = ~np.eye(len(channels), dtype=bool)
    for k in range(mountings):
        mount = model._draw(rng, masses_g, block_mass_g)
        for i, name in enumerate(names):
            ratio = mount.motion_ratio(name, f)
            magnitude[i] += (100.0 * (np.abs(ratio) - 1.0)) ** 2
            phase[i] += np.degrees(np.angle(ratio)) ** 2
        coupling[k] = np.abs(mount.crosstalk(f, channels)[:, off]).max()
    terms = []
    for i, name in enumerate(names):
        u_mag = np.maximum(margin * np.sqrt(magnitude[i] / mountings), floor_percent)
        u_phase = np.maximum(margin * np.sqrt(phase[i] / mountings), floor_deg)
        terms.append(
            StatedTerm(
                name,
                tuple((float(x), _round_up(float(v))) for x, v in zip(f, u_mag, strict=True)),
                tuple((float(x), _round_up(float(v))) for x, v in zip(f, u_phase, strict=True)),
            )
        )
    crosstalk_db = math.ceil(20.0 * math.log10(margin * math.sqrt(np.mean(coupling**2))))
    return terms, float(crosstalk_db)


def interpolated(rows: Sequence[tuple[float, float]], frequency_hz: np.ndarray) -> np.ndarray:
    """A stated table's value at the frequencies (Hz): log-log interpolated between its rows,
    held flat outside them (the design's reading of `relative_motion`)."""
    f = np.asarray(rows, dtype=np.float64)
    x = np.log(np.asarray(frequency_hz, dtype=np.float64))
    return np.exp(np.interp(x, np.log(f[:, 0]), np.log(f[:, 1])))


def _round_up(value: float) -> float:
    """`value` rounded up to two significant digits (a stated figure never below its source)."""
    if value <= 0:
        return 0.0
    scale = 10.0 ** (math.floor(math.log10(value)) - 1)
    return math.ceil(value / scale - 1e-9) * scale


def _scatter(table: Mapping[str, Any]) -> MountingScatter | None:
    """The table's mounting scatter; None when it states none."""
    keys = ("mounting_offset_mm", "rocking_scatter", "crosstalk_scatter")
    if not any(k in table for k in keys):
        return None
    return MountingScatter(
        mounting_offset_m=_number(table, "mounting_offset_mm", 0.0, 100.0, 0.0) * 1e-3,
        rocking_scatter=_number(table, "rocking_scatter", 0.0, 1.0, 0.0),
        crosstalk_scatter=_number(table, "crosstalk_scatter", 0.0, 3.0, 0.0),
    )


def _positions(positions: Sequence[PositionGeometry]) -> dict[str, PositionGeometry]:
    out: dict[str, PositionGeometry] = {}
    for p in positions:
        if p.name in out:
            raise InputRefused(f"fixture position {p.name!r}: named twice")
        if not (math.isfinite(p.distance_m) and 0.0 <= p.distance_m <= 10.0):
            raise InputRefused(
                f"fixture position {p.name!r}: distance {p.distance_m!r} m is not 0-10 m"
            )
        if not math.isfinite(p.azimuth_deg):
            raise InputRefused(f"fixture position {p.name!r}: azimuth {p.azimuth_deg!r} degrees")
        out[p.name] = p
    return out


def _frequencies(frequency_hz: np.ndarray) -> np.ndarray:
    f = np.asarray(frequency_hz, dtype=np.float64)
    if not np.all(np.isfinite(f)) or np.any(f < 0):
        raise InputRefused("fixture: frequencies must be finite and >= 0 Hz")
    return f


def _number(
    table: Mapping[str, Any],
    key: str,
    low: float,
    high: float,
    default: float | None = None,
    *,
    where: str = f"[{TABLE}]",
) -> float:
    """table[key] as a float within [low, high]; InputRefused naming the key otherwise."""
    if key not in table:
        if default is None:
            raise InputRefused(f"{where} {key}: missing ({KEYS[key][1]})")
        return default
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, int | float):
        meaning = f" ({KEYS[key][1]})" if key in KEYS else ""
        raise InputRefused(f"{where} {key}: {value!r} is not a number{meaning}")
    number = float(value)
    if not (math.isfinite(number) and low <= number <= high):
        raise InputRefused(f"{where} {key}: {number:g} is not within {low:g}..{high:g}")
    return number


def _pair(table: Mapping[str, Any], key: str, low: float, high: float) -> tuple[float, float]:
    """A number for both horizontal axes, or [about x, about y]."""
    value = table[key]
    if isinstance(value, list | tuple):
        if len(value) != 2:
            raise InputRefused(f"[{TABLE}] {key}: {len(value)} values; give one or [x, y]")
        first, second = (_number({key: v}, key, low, high) for v in value)
        return first, second
    one = _number(table, key, low, high)
    return one, one
