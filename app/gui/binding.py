"""Refuse a Qt binding known to corrupt reference counts before any window opens.

PySide6 6.12.0 on Python 3.11 drops one reference to ``True`` per queued signal emission and
one to ``None`` per ``QLabel.setText`` (measured: 200 calls, 200 references lost; 6.11.3 loses
none). On Python 3.11 these objects are not immortal, so after enough GUI updates the count
reaches zero and the interpreter aborts with "Fatal Python error: none_dealloc" (or
bool_dealloc), in whatever code happens to drop the last reference: in a run, that was
pyqtgraph's axis code. pyproject.toml pins ``PySide6-Essentials<6.12``; this check catches an
environment installed some other way.
"""

from __future__ import annotations

import gc
import logging
import sys

log = logging.getLogger(__name__)

# (first bad, first good again or None) on Pythons whose None/True/False are not immortal
KNOWN_BAD = (((6, 12, 0), None),)
IMMORTAL_SINGLETONS = (3, 12)  # from Python 3.12 on, None/True/False cannot be deallocated


def _version(text: str) -> tuple[int, ...]:
    parts = []
    for piece in text.split(".")[:3]:
        digits = "".join(c for c in piece if c.isdigit())
        parts.append(int(digits or 0))
    return tuple(parts)


def known_bad(version: str, python: tuple[int, int] | None = None) -> bool:
    """Whether PySide6 `version` is a release known to lose references to None/True on
    Python `python` (default: this interpreter)."""
    python = python or sys.version_info[:2]
    if python >= IMMORTAL_SINGLETONS:
        return False
    v = _version(version)
    return any(v >= bad and (good is None or v < good) for bad, good in KNOWN_BAD)


def loses_references(calls: int = 64) -> bool:
    """Measure: does emitting a queued signal and setting a label's text lose references to
    True or None? Needs a QApplication; about a millisecond."""
    from PySide6.QtCore import QObject, Signal
    from PySide6.QtWidgets import QApplication, QLabel

    class _Probe(QObject):
        fired = Signal(object)

    app = QApplication.instance()
    if app is None:
        raise RuntimeError("loses_references() needs a QApplication")
    probe, label = _Probe(), QLabel()
    probe.fired.connect(lambda value: None)
    enabled = gc.isenabled()
    gc.disable()
    try:
        before = sys.getrefcount(None), sys.getrefcount(True)
        for _ in range(calls):
            probe.fired.emit(True)
            label.setText("probe")
        after = sys.getrefcount(None), sys.getrefcount(True)
    finally:
        if enabled:
            gc.enable()
    label.deleteLater()
    lost = max(b - a for a, b in zip(after, before, strict=True))
    return lost >= calls // 2


def qt_binding_problem(version: str | None = None, *, probe: bool = True) -> str | None:
    """Why the installed Qt binding must not run the window (None: it may). `version` for
    tests; `probe` also measures the binding (needs a QApplication)."""
    if version is None:
        import PySide6

        version = PySide6.__version__
    python = ".".join(map(str, sys.version_info[:3]))
    advice = (
        "Install a fixed one: pip install 'PySide6-Essentials>=6.6,<6.12' (or make venv, "
        "which installs the pinned version)."
    )
    if known_bad(version):
        return (
            f"PySide6 {version} on Python {python} is known to lose references to None and "
            f"True; the window would crash with 'Fatal Python error: none_dealloc'. {advice}"
        )
    if probe and loses_references():
        return (
            f"PySide6 {version} on Python {python} loses references to None or True (measured "
            f"at start); the window would crash with 'Fatal Python error: none_dealloc'. {advice}"
        )
    return None
