"""What both VISA drivers share: opening the resource (termination '\\n' both ways), closing
it once, the set/query helpers over declared `Setting`s and VISA error translation.

A driver owns the resource it was given or opened: `close()` closes it (once; further calls do
nothing). A resource manager passed in, or created here, is never closed by the driver, since
pyvisa shares one manager between all resources of a library. After a timeout the
instrument's late answer may still be in its output queue; close and reopen the driver before
using it again.
"""

from __future__ import annotations

from typing import Any, ClassVar, TypeVar

import pyvisa
from pyvisa import errors as visa_errors

from hardware.errors import DeviceLostError, HardwareError, InstrumentError
from hardware.visa_amplifiers.settings import (
    Setting,
    VisaResourceLike,
    parse_text,
    translate_visa_error,
)

T = TypeVar("T")

TERMINATION = "\n"
DEFAULT_TIMEOUT_MS = 2000


def _open_resource(
    name: str, resource_manager: pyvisa.ResourceManager | None, timeout_ms: int, label: str
) -> VisaResourceLike:
    if resource_manager is None:
        try:
            resource_manager = pyvisa.ResourceManager()
        except (OSError, ValueError) as exc:
            raise HardwareError(
                f"{label}: no VISA library found ({exc}); install NI-VISA or pyvisa-py"
            ) from exc
    try:
        resource = resource_manager.open_resource(
            name,
            read_termination=TERMINATION,
            write_termination=TERMINATION,
            timeout=timeout_ms,
        )
    except (visa_errors.VisaIOError, visa_errors.InvalidSession) as exc:
        raise translate_visa_error(exc, label, "open") from exc
    if not isinstance(resource, pyvisa.resources.MessageBasedResource):
        resource.close()
        raise InstrumentError(f"{label}: {name} is not a message-based instrument")
    return resource


class VisaInstrument:
    """Open/close, error translation and the set/query helpers shared by both drivers."""

    kind: ClassVar[str] = "VISA instrument"

    def __init__(
        self,
        resource: str | VisaResourceLike,
        resource_manager: pyvisa.ResourceManager | None = None,
        *,
        timeout_ms: int = DEFAULT_TIMEOUT_MS,
    ) -> None:
        self._identity: str | None = None
        self._resource: VisaResourceLike | None = None
        if isinstance(resource, str):
            self.resource_name = resource
            self.label = f"{self.kind} at {resource}"
            self._resource = _open_resource(resource, resource_manager, timeout_ms, self.label)
        else:
            self.resource_name = str(getattr(resource, "resource_name", "") or "")
            where = self.resource_name or type(resource).__name__
            self.label = f"{self.kind} at {where}"
            self._resource = resource

    # --- low level

    def _require_open(self, command: str) -> VisaResourceLike:
        if self._resource is None:
            raise DeviceLostError(f"{self.label}: closed, cannot send {command!r}")
        return self._resource

    def _write(self, command: str) -> None:
        resource = self._require_open(command)
        try:
            resource.write(command)
        except (visa_errors.VisaIOError, visa_errors.InvalidSession) as exc:
            raise translate_visa_error(exc, self.label, command) from exc

    def _query(self, command: str) -> str:
        """The answer to `command`, termination and surrounding blanks removed."""
        resource = self._require_open(command)
        try:
            answer = resource.query(command)
        except (visa_errors.VisaIOError, visa_errors.InvalidSession) as exc:
            raise translate_visa_error(exc, self.label, command) from exc
        except UnicodeDecodeError as exc:
            raise InstrumentError(
                f"{self.label}: answer to {command!r} is not text: {exc.object!r}"
            ) from exc
        return str(answer).strip()

    def _clean_answer(self, answer: str) -> str:
        """The value part of an answer to a setting's query (drivers strip echoed headers)."""
        return answer

    # --- declarative settings

    def _set(self, setting: Setting[Any], value: object, **path: object) -> None:
        self._write(setting.command(value, self.label, **path))

    def _get(self, setting: Setting[T], **path: object) -> T:
        answer = self._clean_answer(self._query(setting.query_command(**path)))
        return setting.parse_answer(answer, self.label, **path)

    # --- common API

    def identify(self) -> str:
        """The instrument's `*IDN?` answer (also kept for the run record)."""
        self._identity = self._get(_IDENTITY)
        return self._identity

    @property
    def closed(self) -> bool:
        return self._resource is None

    def close(self) -> None:
        """Close the resource; calling it again does nothing."""
        resource, self._resource = self._resource, None
        if resource is None:
            return
        try:
            resource.close()
        except (visa_errors.VisaIOError, visa_errors.InvalidSession) as exc:
            raise translate_visa_error(exc, self.label, "close") from exc

    def __enter__(self):
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "closed" if self.closed else "open"
        return f"<{type(self).__name__} {self.label} ({state})>"


_IDENTITY: Setting[str] = Setting("identity", query="*IDN?", parse=parse_text)
