"""The procedure's modes (CLI choices, GUI list, settings, certificate), importable light: the
`Mode` StrEnum (its home: app.io.vocabulary), its members as the old constant names, and the
stepped sine's default block."""

from app.io.vocabulary import Mode

MODES = tuple(m.value for m in Mode)  # plain strings: argparse quotes choices by repr()
MODE_MULTISINE = Mode.MULTISINE  # old names of the members, kept for one release
MODE_STEPPED_SINE = Mode.STEPPED_SINE

# The stepped sine's shortest block per sine fit (s; whole cycles of the line and the mains):
# the best of 0.05, 0.1 and 0.25 s in docs/benchmarks.md table 2 wherever the target binds
# nowhere (27.5 s against 31.4 s and 52.3 s warm on the seed plan: each line pays its fade-in,
# level loop and settle in blocks, so the overhead per line scales with the block) and within
# the spread of the three where it binds; `accelcal run --stepped-block` sets another.
DEFAULT_STEPPED_BLOCK_S = 0.05

__all__ = ["DEFAULT_STEPPED_BLOCK_S", "MODES", "MODE_MULTISINE", "MODE_STEPPED_SINE", "Mode"]
