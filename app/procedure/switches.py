"""Help texts of the run's and the plan's options shared by the command line and the GUI,
importable light (no numpy, no plans, no stand): `accelcal plan` is parsed without the run's
options table (app.cli.plan_parser, issue 34 point 3)."""

from __future__ import annotations

# The help of the run's switches (the command line's flags, the GUI's check boxes): one text each
EXACT_MAINS_HELP = (
    "keep lines on mains harmonics on their exact bins (default: each moved one bin, "
    "alternately up and down, and stated at its actual frequency; a line kept there cannot be "
    "told from hum while driven)"
)

# the sample rate and period are bounded by this machine as well (app.procedure.capacity)
CAPACITY_NOTE = "refused before anything moves when this machine has not the memory for it"

__all__ = ["CAPACITY_NOTE", "EXACT_MAINS_HELP"]
