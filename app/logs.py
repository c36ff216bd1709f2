"""Logging for the command line: warnings on stderr (with --verbose, everything a run writes to
its run.log too), and a traceback of any unexpected error kept in the user's log file, so the
user sees one line and the traceback is not lost."""

from __future__ import annotations

import logging
import os
import sys
import traceback
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

LOG_ENV = "ACCELCAL_LOG"  # a file to keep tracebacks in instead of the user's log directory


def log_path() -> Path:
    """Where tracebacks of unexpected errors go: $ACCELCAL_LOG, else the user's log folder."""
    if os.environ.get(LOG_ENV):
        return Path(os.environ[LOG_ENV])
    from platformdirs import user_log_dir

    return Path(user_log_dir("accelcal", appauthor=False)) / "accelcal.log"


class _Stderr(logging.StreamHandler):  # type: ignore[type-arg]
    """A handler writing to whatever sys.stderr is at the time (tests replace it)."""

    @property  # type: ignore[override]
    def stream(self) -> Any:
        return sys.stderr

    @stream.setter
    def stream(self, _value: Any) -> None:
        pass


def setup(verbose: bool) -> logging.Handler:
    """Log records to stderr: warnings and errors, and with `verbose` information too (a run's
    states and warnings as its run.log has them). Returns the handler (see `teardown`)."""
    root = logging.getLogger()
    root.setLevel(logging.DEBUG if verbose else logging.INFO)
    for handler in [h for h in root.handlers if getattr(h, "_accelcal", False)]:
        root.removeHandler(handler)
    handler = _Stderr()
    handler.setLevel(logging.INFO if verbose else logging.WARNING)
    handler.setFormatter(logging.Formatter("accelcal: %(levelname)s: %(name)s: %(message)s"))
    handler._accelcal = True  # type: ignore[attr-defined]
    root.addHandler(handler)
    return handler


def teardown(handler: logging.Handler) -> None:
    """Remove the handler `setup` added (a command has ended; callers in-process go on)."""
    logging.getLogger().removeHandler(handler)


def keep_traceback(command: str, exc: BaseException) -> Path | None:
    """Append the traceback of `exc` to the log file; its path, or None if it cannot be kept."""
    path = log_path()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        stamp = datetime.now(UTC).isoformat(timespec="seconds")
        text = "".join(traceback.format_exception(exc))
        with path.open("a", encoding="utf-8") as handle:
            handle.write(f"--- {stamp} accelcal {command}\n{text}")
    except OSError:
        return None
    return path
