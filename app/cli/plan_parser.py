"""`accelcal plan`'s options, importable light (issue 34 point 3): app.cli parses a `plan`
command with this parser alone, so that it imports neither the run's options table nor the
simulated stand's models; app.cli.parser adds the same options to the full parser (plan, run,
simulate). The simulated exciters' names are looked up when argparse checks or lists them."""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Iterator, Sequence
from typing import overload

from app.cli.options import FADE_IN, FREQUENCY, LEVEL, MAINS, PERIOD, SAMPLE_RATE, numeric_option
from app.procedure.switches import CAPACITY_NOTE, EXACT_MAINS_HELP
from dsp.multisine import PRESETS
from dsp.profiles import Profile


class LazyNames(Sequence[str]):
    """The names `attribute` of `module` holds, imported on first use (argparse's `choices`:
    checked only when the option is given, listed only by --help or a refusal)."""

    def __init__(self, module: str, attribute: str) -> None:
        self.module, self.attribute = module, attribute
        self._names: tuple[str, ...] | None = None

    def _loaded(self) -> tuple[str, ...]:
        if self._names is None:
            self._names = tuple(getattr(importlib.import_module(self.module), self.attribute))
        return self._names

    @overload
    def __getitem__(self, index: int) -> str: ...

    @overload
    def __getitem__(self, index: slice) -> Sequence[str]: ...

    def __getitem__(self, index: int | slice) -> str | Sequence[str]:
        return self._loaded()[index]

    def __len__(self) -> int:
        return len(self._loaded())

    def __iter__(self) -> Iterator[str]:
        return iter(self._loaded())

    def __contains__(self, value: object) -> bool:
        return value in self._loaded()


EXCITER_NAMES = LazyNames("app.stand.simulated", "EXCITERS")  # the simulated stand's exciters


def add_plan_options(p: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """The plan's lines, rate, period, level, reference and mains (plan, and simulate's CSV)."""
    p.add_argument("--preset", choices=sorted(PRESETS), help="named plan (default piezo)")
    p.add_argument("--frequencies", help="line list in Hz, e.g. 10,12.5,...,2500 (ISO 266 fill)")
    numeric_option(p, "--sample-rate", SAMPLE_RATE, f"sample rate in Hz ({CAPACITY_NOTE})")
    numeric_option(p, "--period", PERIOD, f"period length in samples ({CAPACITY_NOTE})")
    numeric_option(p, "--level", LEVEL, "target peak acceleration per line, e.g. 5 or 0.5g")
    numeric_option(p, "--reference-frequency", FREQUENCY, "reference frequency in Hz")
    numeric_option(p, "--mains", MAINS, "mains frequency in Hz (50)", default=None)
    p.add_argument("--exact-mains-bins", action="store_true", help=EXACT_MAINS_HELP)


def add_range_options(p: argparse.ArgumentParser) -> None:
    """Issue 26: the whole range from the command line (run and plan)."""
    g = p.add_argument_group("range (issue 26): lines, rate, period, profile, exciter")
    if p.prog.endswith(" run"):  # plan has these among its plan options
        g.add_argument("--frequencies", help="line list in Hz, e.g. 0.4,...,8 (ISO 266 fill)")
        numeric_option(g, "--sample-rate", SAMPLE_RATE, f"sample rate in Hz ({CAPACITY_NOTE})")
        numeric_option(g, "--period", PERIOD, f"period in samples ({CAPACITY_NOTE})")
        numeric_option(g, "--reference-frequency", FREQUENCY, "reference frequency in Hz")
    g.add_argument(
        "--profile",
        choices=[p.value for p in Profile],
        default=Profile.ACCELERATION.value,
        help="per-line level: constant acceleration, or constant velocity or displacement "
        "below --corner (then --level above it); every line clipped by the exciter's stroke",
    )
    numeric_option(g, "--corner", FREQUENCY, "corner frequency of the profile, Hz")
    g.add_argument(
        "--exciter",
        choices=EXCITER_NAMES,
        help="simulated stand's exciter (long-stroke: 150 mm, 0.4 Hz up); its stroke clips "
        "and checks the plan",
    )
    if p.prog.endswith(" run"):
        numeric_option(
            g,
            "--fade-in",
            FADE_IN,
            "lpm: fade-in before the record, s (default one cycle of the lowest line, longer "
            "near the stroke)",
        )


def add_plan_command(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """`accelcal plan` and its options, on the top-level subparsers."""
    p = sub.add_parser("plan", help="show a frequency plan, its checks and predicted peaks")
    add_plan_options(p)
    p.add_argument(
        "--shift-mains",
        action="store_true",
        help="move lines off mains harmonics (the default; kept for old scripts)",
    )
    add_range_options(p)
    p.add_argument("--json", action="store_true", help="machine-readable output")
    return p
