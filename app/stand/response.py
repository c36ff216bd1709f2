"""The stand's measured response per line, kept between runs (issue 14 point 1).

After a run's equalisation has converged, the response it found (table acceleration per drive
volt, complex, (m/s^2)/V, at the run's level: the exciter's compression and the harmonics that
land on lines are in it) is kept per stand (the SHA-256 of its stand file, and for the
simulated stand its seed), DUT mass class and plan lines (sample rate, period, bins), with its
date and the run that measured it. The next run of that stand, mass class and plan starts
equalisation from it instead of a gentle identification; its first settled period checks it.

This is a cache of the stand's state, not a record: an entry of the same level is replaced by
a newer one, an unreadable file is ignored (the run identifies), and the run record names the
entry it used (date, run, stand hash), so what a run started from is always traceable.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import math
import os
import stat
import tempfile
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from dsp.multisine import Plan

log = logging.getLogger(__name__)

FORMAT_VERSION = 1
MAX_STORE_BYTES = 8 * 1024 * 1024  # a store file is a few kB per level; larger is not ours
# DUT mass classes (g): the exciter's response changes with the moving mass (sim.models
# ExciterModel.loaded); a response is only reused for a DUT of the same class
MASS_CLASSES: tuple[tuple[float, str], ...] = (
    (25.0, "up to 25 g"),
    (100.0, "25-100 g"),
    (300.0, "100-300 g"),
    (math.inf, "over 300 g"),
)
MASS_UNSTATED = "mass not stated"


def mass_class(mass_g: float | None) -> str:
    """The mass class of a DUT of `mass_g` grams (None: not stated)."""
    if mass_g is None:
        return MASS_UNSTATED
    if not (math.isfinite(mass_g) and mass_g >= 0):
        raise ValueError(f"DUT mass: must be >= 0 g, got {mass_g:g}")
    return next(name for upper, name in MASS_CLASSES if mass_g <= upper)


def stand_sha256(stand_text: str) -> str:
    """SHA-256 of the stand file's text as read (the key the records use for a stand)."""
    return hashlib.sha256(stand_text.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class StoredResponse:
    """One measured response: where, what, when, and the complex response per line."""

    stand_sha256: str
    realisation: str  # "" for real hardware; the simulated stand's seed
    mode: str  # multisine or stepped-sine: the response at one line alone differs a little
    mass_class: str
    sample_rate_hz: float
    period_samples: int
    bins: tuple[int, ...]
    levels_ms2: tuple[float, ...]  # per line, peak
    phases_rad: tuple[float, ...]
    response: np.ndarray  # complex, (m/s^2)/V per line
    measured_utc: str  # ISO 8601
    run_id: str | None
    worst_error: float  # the equalisation error (fraction) at the drive it gave

    def age_days(self, now: datetime) -> float:
        """Days since it was measured."""
        return (now - datetime.fromisoformat(self.measured_utc)).total_seconds() / 86400.0

    def summary(self) -> dict[str, Any]:
        """What the run record keeps of it."""
        return {
            "stand_sha256": self.stand_sha256,
            "mass_class": self.mass_class,
            "measured_utc": self.measured_utc,
            "run_id": self.run_id,
            "levels_ms2": [min(self.levels_ms2), max(self.levels_ms2)],
        }

    def to_dict(self) -> dict[str, Any]:
        return {
            "stand_sha256": self.stand_sha256,
            "realisation": self.realisation,
            "mode": self.mode,
            "mass_class": self.mass_class,
            "sample_rate_hz": self.sample_rate_hz,
            "period_samples": self.period_samples,
            "bins": list(self.bins),
            "levels_ms2": list(self.levels_ms2),
            "phases_rad": list(self.phases_rad),
            "response_real": self.response.real.tolist(),
            "response_imag": self.response.imag.tolist(),
            "measured_utc": self.measured_utc,
            "run_id": self.run_id,
            "worst_error": self.worst_error,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> StoredResponse:
        """An entry as stored; ValueError when any field is missing or implausible."""
        try:
            bins = tuple(int(b) for b in d["bins"])
            response = np.asarray(d["response_real"], float) + 1j * np.asarray(
                d["response_imag"], float
            )
            entry = cls(
                stand_sha256=str(d["stand_sha256"]),
                realisation=str(d["realisation"]),
                mode=str(d["mode"]),
                mass_class=str(d["mass_class"]),
                sample_rate_hz=float(d["sample_rate_hz"]),
                period_samples=int(d["period_samples"]),
                bins=bins,
                levels_ms2=tuple(float(a) for a in d["levels_ms2"]),
                phases_rad=tuple(float(p) for p in d["phases_rad"]),
                response=response,
                measured_utc=str(d["measured_utc"]),
                run_id=None if d["run_id"] is None else str(d["run_id"]),
                worst_error=float(d["worst_error"]),
            )
            datetime.fromisoformat(entry.measured_utc)
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"stored response: {exc}") from None
        n = len(bins)
        if not (len(entry.levels_ms2) == len(entry.phases_rad) == response.size == n):
            raise ValueError("stored response: lines, levels, phases and response differ in length")
        if not (np.all(np.isfinite(response)) and np.all(np.abs(response) > 0)):
            raise ValueError("stored response: not finite or zero at some line")
        return entry


@dataclass(frozen=True)
class Lookup:
    """The entry to start from (or None) and why: said in run.log and the run record."""

    entry: StoredResponse | None
    reason: str


class ResponseStore:
    """Stored responses in a folder: one JSON file per stand, mass class and plan lines, each
    holding one entry per level."""

    def __init__(self, root: Path):
        self.root = Path(root)

    @classmethod
    def default(cls) -> ResponseStore:
        """In the user's data directory (app.files.data_dir: $ACCELCAL_DATA_DIR, else
        platformdirs), beside the records database."""
        from app.files import data_dir

        return cls(data_dir() / "stand-responses")

    def _file(
        self,
        stand: str,
        realisation: str,
        mode: str,
        mass: str,
        fs: float,
        n: int,
        bins: tuple[int, ...],
    ) -> Path:
        key = json.dumps([realisation, mode, mass, fs, n, list(bins)])
        name = hashlib.sha256(key.encode()).hexdigest()[:24]
        return self.root / stand[:32] / f"{name}.json"

    def _entries(self, path: Path) -> list[StoredResponse]:
        """The entries of `path`; none when it is missing, and none (logged) when unreadable."""
        try:
            data = json.loads(read_store_file(path).decode("utf-8"))
        except FileNotFoundError:
            return []
        except (OSError, ValueError) as exc:
            log.warning("stored response %s unreadable (%s): ignored", path, exc)
            return []
        try:
            if data.get("format") != FORMAT_VERSION:
                raise ValueError(f"format {data.get('format')!r}, expected {FORMAT_VERSION}")
            return [StoredResponse.from_dict(e) for e in data["entries"]]
        except (AttributeError, KeyError, TypeError, ValueError) as exc:
            log.warning("stored response %s ignored: %s", path, exc)
            return []

    def lookup(
        self,
        stand: str,
        realisation: str,
        mode: str,
        mass: str,
        plan: Plan,
        *,
        now: datetime,
        max_age_days: float,
    ) -> Lookup:
        """The entry of this stand, mass class and plan lines closest in level to the plan's,
        if one is at most `max_age_days` old; else None with the reason."""
        bins = tuple(int(b) for b in plan.bins)
        path = self._file(
            stand, realisation, mode, mass, plan.sample_rate_hz, plan.period_samples, bins
        )
        entries = [
            e
            for e in self._entries(path)
            if e.stand_sha256 == stand
            and e.realisation == realisation
            and e.mode == mode
            and e.mass_class == mass
            and e.sample_rate_hz == plan.sample_rate_hz
            and e.period_samples == plan.period_samples
            and e.bins == bins
        ]
        if not entries:
            return Lookup(None, f"no stored response for this stand, {mass} and plan")
        fresh = [e for e in entries if 0 <= e.age_days(now) <= max_age_days]
        if not fresh:
            newest = max(entries, key=lambda e: e.measured_utc)
            return Lookup(
                None,
                f"stored response of {newest.measured_utc} is older than {max_age_days:g} days",
            )
        levels = np.asarray(plan.amplitudes_ms2, float)

        def distance(e: StoredResponse) -> float:
            return float(np.max(np.abs(np.log(np.asarray(e.levels_ms2) / levels))))

        best = min(fresh, key=lambda e: (distance(e), -e.age_days(now)))
        return Lookup(
            best,
            f"stored response of {best.measured_utc} (run {best.run_id}, {mass}, "
            f"{best.age_days(now):.1f} days old)",
        )

    def save(self, entry: StoredResponse) -> Path:
        """Keep `entry`, replacing one of the same level (to 0.1 %); atomic (temporary file,
        then renamed over the old one: a reader sees the old file or the new one)."""
        path = self._file(
            entry.stand_sha256,
            entry.realisation,
            entry.mode,
            entry.mass_class,
            entry.sample_rate_hz,
            entry.period_samples,
            entry.bins,
        )
        same = np.asarray(entry.levels_ms2)
        kept = [
            e
            for e in self._entries(path)
            if not (
                len(e.levels_ms2) == same.size
                and np.allclose(np.asarray(e.levels_ms2), same, rtol=1e-3, atol=0.0)
            )
        ]
        kept.append(entry)
        text = json.dumps({"format": FORMAT_VERSION, "entries": [e.to_dict() for e in kept]})
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, temporary = tempfile.mkstemp(prefix=".response-", dir=path.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(text)
                f.flush()
                os.fsync(f.fileno())
            os.replace(temporary, path)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(temporary)
            raise
        return path


def read_store_file(path: Path, max_bytes: int = MAX_STORE_BYTES) -> bytes:
    """The bytes of a stored-response file, read safely (issue 25 point 7): lstat first (a
    regular file, not a symlink, FIFO or device, at most `max_bytes`), then opened with
    O_NONBLOCK and O_NOFOLLOW (a FIFO swapped in cannot block the run with the power amplifier
    on), fstat checked to be the same regular file, and at most `max_bytes` + 1 read.
    FileNotFoundError when missing; ValueError naming the file and the reason otherwise."""
    before = os.lstat(path)
    if not stat.S_ISREG(before.st_mode):
        raise ValueError(f"{path}: not a regular file")
    if before.st_size > max_bytes:
        raise ValueError(f"{path}: {before.st_size} bytes, over the {max_bytes} byte bound")
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise ValueError(f"{path}: cannot be opened safely ({exc.strerror})") from None
    try:
        after = os.fstat(fd)
        if not stat.S_ISREG(after.st_mode) or (after.st_dev, after.st_ino) != (
            before.st_dev,
            before.st_ino,
        ):
            raise ValueError(f"{path}: changed while being opened")
        chunks, total = [], 0
        while total <= max_bytes:
            chunk = os.read(fd, min(1 << 20, max_bytes + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
        if total > max_bytes:
            raise ValueError(f"{path}: over the {max_bytes} byte bound")
        return b"".join(chunks)
    finally:
        os.close(fd)


def now_utc() -> datetime:
    """The current time, UTC (one place, so tests can see what a run compares ages with)."""
    return datetime.now(UTC)
