"""Python's cyclic garbage collector run on the GUI thread only.

The window's run and import workers are Python threads. Left automatic, a collection starts in
whichever thread happens to allocate, and it may free Qt objects (a closed dialog, a plot item
in a reference cycle) there, off the thread that owns them: Qt then deadlocks or crashes the
process (seen: a test process killed by SIGSEGV inside a collection started by a web request's
thread; a pyqtgraph window freed by a collection in a plain thread hung for good). While the
window is open, automatic collection is off and pyqtgraph's `GarbageCollector` collects on a
timer of the GUI thread, by generation, at the thresholds Python itself would use.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager

CHECK_INTERVAL_S = 0.25
"""How often the GUI thread looks at the collector's counts, s (a generation-0 collection of a
quarter second of a run's allocations takes well under a millisecond)."""


@contextmanager
def collected_on_gui_thread(interval_s: float = CHECK_INTERVAL_S) -> Iterator[object]:
    """Within the block, cyclic garbage is collected only by a timer of the calling (GUI)
    thread; afterwards automatic collection is as it was. Needs a Q(Core)Application."""
    from pyqtgraph.util.garbage_collector import GarbageCollector

    was_enabled = gc.isenabled()
    collector = GarbageCollector(interval=interval_s)  # disables automatic collection
    try:
        yield collector
    finally:
        collector.timer.stop()
        if was_enabled:
            gc.enable()
