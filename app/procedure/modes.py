"""The procedure's modes (CLI choices, GUI list, settings, certificate), importable light: the
`Mode` StrEnum (its home: app.io.vocabulary), its members as the old constant names, and the
stepped sine's default block."""

from app.io.vocabulary import Mode

MODES = tuple(m.value for m in Mode)  # plain strings: argparse quotes choices by repr()
MODE_MULTISINE = Mode.MULTISINE  # old names of the members, kept for one release
MODE_STEPPED_SINE = Mode.STEPPED_SINE

# The stepped sine's shortest block per sine fit (s; whole cycles of the line and the mains).
# docs/benchmarks.md table 2 (python bench/excitation_time.py, warm, fair grid): 0.05 s is the
# best of 0.05, 0.1 and 0.25 s wherever the target binds nowhere, the usual case (seed plan at
# 0.2 %: 19.7 s against 22.2 s and 36.9 s; each line pays its fade-in, level loop and settle
# in blocks, so the overhead per line scales with the block); where the target binds at every
# line (0.05 m/s^2) 0.25 s is best, and 0.05 s costs 9 % more at 0.05 % (127.9 s against
# 116.8 s) and 0.6 % at 0.02 % (793.7 s against 788.7 s). `--stepped-block` sets another.
DEFAULT_STEPPED_BLOCK_S = 0.05

__all__ = ["DEFAULT_STEPPED_BLOCK_S", "MODES", "MODE_MULTISINE", "MODE_STEPPED_SINE", "Mode"]
