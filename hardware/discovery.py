"""What hardware this computer can see: NI DAQ devices and VISA instruments (`accelcal devices`).

list_ni_devices()        -> [{"name", "product_type", "ai", "ao"}]  (DaqNotFoundError if
                            the NI-DAQmx driver is missing)
list_visa_resources(rm)  -> [{"resource", "idn", "error"}]  (*IDN? answer, or the error text)
describe()               -> a readable report that says what is missing; never raises
"""

from __future__ import annotations

from typing import Any

from hardware.errors import HardwareError
from hardware.nidaq import import_nidaqmx, not_installed_message, translate_error

#: *IDN? timeout for each VISA resource (ms): an instrument that does not answer is skipped fast.
IDN_TIMEOUT_MS = 2000


def list_ni_devices(system: Any = None) -> list[dict[str, Any]]:
    """The NI-DAQmx devices present: name, product type, AI and AO physical channel names."""
    try:
        if system is None:
            system = import_nidaqmx().system.System.local()
        devices = list(system.devices)
    except Exception as exc:
        raise translate_error(exc, "NI-DAQmx") from None
    found = []
    for device in devices:
        entry: dict[str, Any] = {"name": str(device.name), "product_type": "", "ai": [], "ao": []}
        try:
            entry["product_type"] = str(device.product_type)
            entry["ai"] = [str(c.name) for c in device.ai_physical_chans]
            entry["ao"] = [str(c.name) for c in device.ao_physical_chans]
        except Exception as exc:  # one odd device must not hide the others
            entry["error"] = str(exc)
        found.append(entry)
    return found


def list_visa_resources(
    resource_manager: Any = None, *, timeout_ms: int = IDN_TIMEOUT_MS
) -> list[dict[str, Any]]:
    """Every VISA resource with its *IDN? answer (None and `error` text if it does not answer).

    A resource manager passed in is left open; one created here is closed. HardwareError if
    no VISA library is installed.
    """
    own = resource_manager is None
    if own:
        try:
            import pyvisa

            resource_manager = pyvisa.ResourceManager()
        except Exception as exc:
            raise HardwareError(
                f"no VISA library: {exc} (install NI-VISA or Keysight IO Libraries, "
                "or `pip install pyvisa-py`)"
            ) from None
    try:
        try:
            names = list(resource_manager.list_resources())
        except Exception as exc:
            raise HardwareError(f"VISA: could not list resources: {exc}") from None
        return [_identify(resource_manager, name, timeout_ms) for name in names]
    finally:
        if own:
            try:
                resource_manager.close()
            except Exception:
                pass


def _identify(resource_manager: Any, name: str, timeout_ms: int) -> dict[str, Any]:
    entry: dict[str, Any] = {"resource": str(name), "idn": None, "error": None}
    try:
        resource = resource_manager.open_resource(
            name, timeout=timeout_ms, read_termination="\n", write_termination="\n"
        )
    except Exception as exc:
        entry["error"] = f"cannot open: {_text(exc)}"
        return entry
    try:
        entry["idn"] = str(resource.query("*IDN?")).strip()
        if entry["idn"].upper().startswith("ERROR"):
            # the B&K 2525 has no *IDN?; it identifies itself to Identify? (manual vol. 2, 9.1)
            answer = str(resource.query("Identify?")).strip()
            # its answers carry a header by default (Header Long, vol. 2 4.3.2): ":Identify ..."
            entry["idn"] = answer.split(None, 1)[1] if answer.startswith(":") else answer
    except Exception as exc:
        entry["error"] = f"no answer to *IDN?: {_text(exc)}"
    finally:
        try:
            resource.close()
        except Exception:
            pass
    return entry


def _text(exc: BaseException) -> str:
    return str(exc).strip() or type(exc).__name__


def describe(resource_manager: Any = None, system: Any = None) -> str:
    """A readable report of the NI DAQ devices and VISA instruments found. Never raises."""
    lines = ["NI-DAQmx devices:"]
    try:
        devices = list_ni_devices(system)
    except Exception as exc:
        message = str(exc) or not_installed_message()
        lines.append(f"  none: {message}")
    else:
        if not devices:
            lines.append(
                "  none found: NI-DAQmx is installed but sees no device; connect and power the "
                "device and check it in NI MAX / NI Hardware Configuration Utility (Linux: "
                "`nilsdev`)"
            )
        for d in devices:
            lines.append(f"  {d['name']}: {d['product_type'] or 'unknown product'}")
            if d.get("error"):
                lines.append(f"    (could not read its channels: {d['error']})")
            else:
                lines.append(f"    AI: {_channels(d['ai'])}")
                lines.append(f"    AO: {_channels(d['ao'])}")
    lines.append("VISA instruments:")
    try:
        resources = list_visa_resources(resource_manager)
    except Exception as exc:
        lines.append(f"  none: {exc}")
    else:
        if not resources:
            lines.append(
                "  none found: check the cables, the instrument's GPIB address or serial "
                "settings, and that it is switched on"
            )
        for r in resources:
            answer = r["idn"] if r["idn"] is not None else r["error"]
            lines.append(f"  {r['resource']}: {answer}")
    return "\n".join(lines)


def _channels(names: list[str]) -> str:
    return ", ".join(names) if names else "none"
