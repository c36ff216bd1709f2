"""mutmut 2.x hooks (docs/mutation.md): in hardware/nidaq.py only the safety paths are mutated.

The safety paths are the functions that bring the drive to 0 V and release the tasks on every
way out of a run, and the ones that gate what reaches the output. Other files: every line.
"""

from __future__ import annotations

import ast
import os
from functools import cache
from pathlib import Path

NIDAQ = "hardware/nidaq.py"
NIDAQ_SAFETY = frozenset(
    {
        "start",  # its except: stop() after a failed start
        "write_period",  # refuses writes before start / after a failure; the drive gate
        "stop",
        "close",
        "output_v",
        "_play_zeros",
        "_zero_on_demand",
        "_period_s",  # how long stop() waits for the zero period to play
        "_write_timeout_s",
        "_checked",
        "_quietly",
    }
)


@cache
def _safety_lines() -> frozenset[int]:
    """1-based line numbers of the bodies of the NIDAQ_SAFETY functions (and FIFO_ALLOWANCE_S)."""
    tree = ast.parse(Path(NIDAQ).read_text())
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef) and node.name in NIDAQ_SAFETY:
            lines.update(range(node.lineno, (node.end_lineno or node.lineno) + 1))
        elif isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "FIFO_ALLOWANCE_S" for t in node.targets
        ):
            lines.add(node.lineno)
    return frozenset(lines)


def _line_window() -> tuple[int, int] | None:
    """MUTMUT_LINES="lo-hi" (1-based, inclusive) mutates only those lines: to split one file's
    run over two processes, each in its own copy of the tree."""
    window = os.environ.get("MUTMUT_LINES")
    if not window:
        return None
    lo, hi = window.split("-")
    return int(lo), int(hi)


def pre_mutation(context) -> None:
    line = context.current_line_index + 1
    if Path(context.filename).as_posix().endswith(NIDAQ) and line not in _safety_lines():
        context.skip = True
    window = _line_window()
    if window is not None and not window[0] <= line <= window[1]:
        context.skip = True
