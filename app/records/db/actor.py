"""Who writes: the default actor of a records write (no database library imported, so a run
that names its operator without records in use stays light)."""

from __future__ import annotations

import getpass


def current_actor() -> str:
    """The operating-system user, the default actor of a write."""
    try:
        return getpass.getuser()
    except (KeyError, OSError):
        return "unknown"
