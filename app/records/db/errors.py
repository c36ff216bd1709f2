"""Errors of the records, in a module that imports nothing heavy (app.cli catches them)."""

from __future__ import annotations

from app.errors import Refusal


class RecordsInputError(Refusal):
    """A refused records operation or option; the message names the field and the reason."""
