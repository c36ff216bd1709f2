"""Mounting remembered per sensor model and per run template (issue 35 point 2): the mounting of
each certificate issued is kept (conditions.json in the user's data directory, app.files
.data_dir) under its model and, when one was chosen, its template; the next certificate of that
model (or template) is offered it, with a visible note "from model X" / "from template T of
model X", instead of having it typed again. Typed values always win; nothing is carried
between models. A damaged file is ignored (logged) and rewritten on the next issue.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from app.files import data_dir, write_new

log = logging.getLogger(__name__)

FILE_NAME = "conditions.json"
KEYS = ("mounting",)  # what is remembered (temperature and humidity are measured each time)


@dataclass(frozen=True)
class Offered:
    """What is offered for a certificate: the mounting and where it is remembered from."""

    mounting: str
    source: str  # "model X" or "template T of model X"

    def note(self) -> str:
        """The note the CLI prints and the GUI shows beside the field."""
        return f"mounting: {self.mounting!r} (from {self.source})"


def _key(model: str, template: str = "") -> str:
    model = " ".join(model.split())
    return f"{model} | template {' '.join(template.split())}" if template.strip() else model


class RememberedConditions:
    """The conditions.json store (`path`; default: the data directory's)."""

    def __init__(self, path: Path | None = None) -> None:
        self.path = path if path is not None else data_dir() / FILE_NAME

    def _read(self) -> dict[str, Any]:
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            return {}
        except (OSError, ValueError) as exc:
            log.warning("%s ignored: %s", self.path, exc)
            return {}
        return data if isinstance(data, dict) else {}

    def offered(self, model: str | None, template: str = "") -> Offered | None:
        """The mounting remembered for `template` of `model`, else for `model`; None."""
        if not model or not model.strip():
            return None
        data = self._read()
        choices = [(_key(model), f"model {model.strip()}")]
        if template.strip():
            choices.insert(
                0, (_key(model, template), f"template {template.strip()} of model {model.strip()}")
            )
        for key, source in choices:
            entry = data.get(key)
            if isinstance(entry, dict) and str(entry.get("mounting") or "").strip():
                return Offered(" ".join(str(entry["mounting"]).split()), source)
        return None

    def remember(self, model: str | None, mounting: str | None, template: str = "") -> None:
        """Keep `mounting` for `model` (and its `template` when given); nothing without both."""
        if not model or not model.strip() or not mounting or not mounting.strip():
            return
        data = self._read()
        entry = {
            "mounting": " ".join(mounting.split()),
            "updated_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        }
        data[_key(model)] = entry
        if template.strip():
            data[_key(model, template)] = entry
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            write_new(self.path, json.dumps(data, indent=2, sort_keys=True), overwrite=True)
        except OSError as exc:  # an offer lost, never a certificate
            log.warning("%s not written: %s", self.path, exc)


def run_model(run: Path, url: str | None) -> str | None:
    """The sensor model a certificate of `run` names when none is typed: the records' model of
    the run's sensor (url: the records in use), else the run's own default (its catalogue DUT
    or the stand file's [certificate] dut_model); None when unknown."""
    from app.certificate.info import default_info
    from app.certificate.load import load_stored_run

    stored = load_stored_run(run)
    if url is not None:
        dut_id = str((stored.record.dut.id if stored.record.dut else None) or "")
        if dut_id:
            from app.records.db.engine import open_engine
            from app.records.db.lab import Lab, RecordsError

            engine = open_engine(url)
            try:
                sensor = Lab(engine).sensor(dut_id)
                return f"{sensor.model.maker} {sensor.model.model}"
            except RecordsError:
                return None
            finally:
                engine.dispose()
    model = default_info(stored.record, stored.start).get("dut_model")
    return str(model) if model else None
