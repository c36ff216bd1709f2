"""mutmut 2.x hooks (docs/mutation.md): in hardware/nidaq.py only the safety paths are mutated.

The safety paths are the functions that bring the drive to 0 V and release the tasks on every
way out of a run, and the ones that gate what reaches the output. Other files: every line.
"""

from __future__ import annotations

import ast
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


def pre_mutation(context) -> None:
    if Path(context.filename).as_posix().endswith(NIDAQ):
        if context.current_line_index + 1 not in _safety_lines():
            context.skip = True
