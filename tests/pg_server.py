"""Starting a private PostgreSQL (pgserver) for a test, safe with parallel test workers
(pytest-xdist): each caller passes its own data folder (the server's socket lives there, so
two workers never share a server), and the starts themselves are taken one at a time."""

from __future__ import annotations

import fcntl
import tempfile
from pathlib import Path
from typing import Any

# one lock file for every test process of this machine: pgserver, run as root, adds its
# `pgserver` system user with an unlocked check-then-useradd that two starts at once can race
_START_LOCK = Path(tempfile.gettempdir()) / "accelcal-tests-pgserver-start.lock"


def start_pgserver(folder: Path) -> Any:
    """A PostgreSQL server with its data (and socket) in `folder`; stopped by its cleanup().
    Raises whatever pgserver raises when it cannot start."""
    import pgserver

    with _START_LOCK.open("a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            return pgserver.get_server(folder, cleanup_mode="stop")
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
