"""The start document of a run: config.json in its folder, written before anything moves.

The one reader and writer of config.json: the stand configuration as used (its TOML as a
table) and where it came from, the plan, the run settings and the run identity. Written with
the layout of earlier versions (json indent 2, these keys in this order), so the file's bytes do
not change and old run folders (one without config.json, or with fewer keys) still load.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from app.errors import Refusal

CONFIG_NAME = "config.json"
_KEYS = ("stand", "stand_source", "plan", "settings", "identity", "batch")


@dataclass(frozen=True)
class BatchMemberLink:
    """One DUT of a batch as every member's config.json names it."""

    position: str
    channel: str
    serial: str
    run_id: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "position": self.position,
            "channel": self.channel,
            "serial": self.serial,
            "run_id": self.run_id,
        }


@dataclass(frozen=True)
class BatchLink:
    """A run that is one DUT of several in one excitation (issue 36): the batch, this DUT's
    position, its channel in the batch recording, the position's distance from the reference
    axis (mm) and every member. config.json's optional "batch" object (absent in a
    single-DUT run, whose file is as before). A triaxial DUT's channel (issue 36 point 3)
    adds the run's `orientation` (its axis along the exciter: x, y or z) and whether this
    channel is `transverse` (a cross channel: analysed without the dead-channel refusal and
    without a verdict, app.procedure.analysis); absent for a single-axis DUT."""

    batch_id: str
    position: str
    channel: str
    distance_mm: float
    members: tuple[BatchMemberLink, ...]
    orientation: str | None = None
    transverse: bool = False

    def to_dict(self) -> dict[str, Any]:
        data: dict[str, Any] = {
            "batch_id": self.batch_id,
            "position": self.position,
            "channel": self.channel,
            "distance_mm": self.distance_mm,
            "members": [m.to_dict() for m in self.members],
        }
        if self.orientation is not None:
            data["orientation"] = self.orientation
            data["transverse"] = self.transverse
        return data

    @classmethod
    def from_dict(cls, data: Any, name: str = CONFIG_NAME) -> BatchLink:
        """The link from config.json's "batch" (RunStartError naming the field)."""
        try:
            members = tuple(
                BatchMemberLink(
                    str(m["position"]), str(m["channel"]), str(m["serial"]), str(m["run_id"])
                )
                for m in data["members"]
            )
            orientation = data.get("orientation")
            transverse = data.get("transverse", False)
            if not isinstance(transverse, bool):
                raise ValueError(f"transverse: true or false, got {transverse!r}")
            return cls(
                str(data["batch_id"]),
                str(data["position"]),
                str(data["channel"]),
                float(data["distance_mm"]),
                members,
                None if orientation is None else str(orientation),
                transverse,
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise RunStartError(f"{name}: batch: not a batch link ({exc})") from None


class RunStartError(Refusal):
    """A config.json that cannot be read; the message names the file and why."""


def _table(value: Any) -> dict[str, Any]:
    return dict(value) if isinstance(value, dict) else {}


@dataclass(frozen=True)
class RunStart:
    """What a run started with. `stand` is None when the folder stored none (the run record's
    stand is then the one to use); `extra` keeps keys this version does not know (written back
    after the known ones)."""

    stand: dict[str, Any] | None = None
    stand_source: str | None = None
    plan: dict[str, Any] = field(default_factory=dict)
    settings: dict[str, Any] = field(default_factory=dict)
    identity: dict[str, Any] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)
    batch: BatchLink | None = None  # one DUT of several in one run (issue 36)

    @property
    def laboratory(self) -> dict[str, Any]:
        """The stand file's [laboratory] table (name, address, country, accreditation)."""
        return _table((self.stand or {}).get("laboratory"))

    @property
    def verify_url(self) -> str | None:
        """The [laboratory] verify_url the run started with, None unset."""
        url = self.laboratory.get("verify_url")
        return str(url) if url else None

    @property
    def reference(self) -> dict[str, Any]:
        """The stand file's [reference] table (id, model, serial, certificate_number, ...)."""
        return _table((self.stand or {}).get("reference"))

    def certificate_defaults(self) -> dict[str, Any]:
        """The stand file's [certificate] table: defaults of the certificate's items."""
        return _table((self.stand or {}).get("certificate"))

    def to_dict(self) -> dict[str, Any]:
        data: dict[str, Any] = dict(
            stand=self.stand,
            stand_source=self.stand_source,
            plan=self.plan,
            settings=self.settings,
            identity=self.identity,
        )
        if self.batch is not None:
            data["batch"] = self.batch.to_dict()
        data.update(self.extra)
        return data

    def to_json(self) -> str:
        """config.json's text (byte-identical to what earlier versions wrote)."""
        return json.dumps(self.to_dict(), indent=2, default=str)

    @classmethod
    def from_json(cls, text: str, name: str = CONFIG_NAME) -> RunStart:
        """A RunStart from config.json's text; RunStartError names `name` and the fault."""
        try:
            data = json.loads(text)
        except ValueError as exc:
            raise RunStartError(f"{name}: not JSON ({exc})") from None
        if not isinstance(data, dict):
            raise RunStartError(f"{name}: not a JSON object")
        stand = data.get("stand")
        if stand is not None and not isinstance(stand, dict):
            raise RunStartError(f"{name}: stand: not a table")
        source = data.get("stand_source")
        return cls(
            stand=stand,
            stand_source=None if source is None else str(source),
            plan=_table(data.get("plan")),
            settings=_table(data.get("settings")),
            identity=_table(data.get("identity")),
            extra={k: v for k, v in data.items() if k not in _KEYS},
            batch=BatchLink.from_dict(data["batch"], name) if "batch" in data else None,
        )

    @classmethod
    def read(cls, folder: Path) -> RunStart:
        """The RunStart of a run folder (an empty one when it has no config.json)."""
        path = folder / CONFIG_NAME
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            return cls()
        except OSError as exc:
            raise RunStartError(f"{path}: cannot be read ({exc.strerror or exc})") from None
        return cls.from_json(text, str(path))
