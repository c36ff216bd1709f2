"""Where a several-DUT run's members after the first spend their time (issue 36's speed): one
unpaced batch of four piezo DUTs on sim/stand-fixture4.toml, its members' analysis after the
run (app.procedure.batch.BatchRun.finish) timed and profiled with cProfile.

Prints the wall time per member after the first, its share of the whole batch run's wall time
(the baseline of the same invocation), the recordings read in it (a count: the same on any
machine) and, with --top N, cProfile's N costliest calls by cumulative time. Wall times only
with `uptime`'s load average: re-measure at idle.

Run: python bench/batch_member_profile.py [--periods P] [--top N] [--smoke]
(--smoke: two DUTs, three periods)
"""

from __future__ import annotations

import argparse
import cProfile
import io
import os
import pstats
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.io import hdf5  # noqa: E402
from app.procedure import batch as batch_module  # noqa: E402
from app.procedure import batch_files  # noqa: E402
from app.procedure.batch import BatchRun, MemberChoice, execute_batch  # noqa: E402
from app.procedure.request import RunRequest  # noqa: E402
from app.stand import config as stand_config  # noqa: E402

STAND = ROOT / "sim" / "stand-fixture4.toml"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--periods", type=int, default=8, help="the request's periods")
    parser.add_argument("--top", type=int, default=0, help="cProfile's costliest calls shown")
    parser.add_argument("--smoke", action="store_true")
    args = parser.parse_args()
    if args.periods < 2 or args.top < 0:
        print("--periods: at least 2; --top: at least 0", file=sys.stderr)
        return 2
    positions = "AB" if args.smoke else "ABCD"
    periods = 3 if args.smoke else args.periods
    profile = cProfile.Profile()
    spent: dict[str, float] = {}
    reads: list[str] = []
    real_finish = BatchRun.finish

    def finish(self: BatchRun, *rest: Any, **named: Any) -> Any:
        start = time.perf_counter()
        profile.enable()
        try:
            return real_finish(self, *rest, **named)
        finally:
            profile.disable()
            spent["finish"] = time.perf_counter() - start

    def counted(path: Any, *rest: Any, **named: Any) -> Any:
        reads.append(str(path))
        return hdf5.read_recording(path, *rest, **named)

    BatchRun.finish = finish  # type: ignore[method-assign]
    batch_files.read_recording = counted  # type: ignore[assignment]
    batch_module.read_recording = counted  # type: ignore[attr-defined]
    out = Path(tempfile.mkdtemp(prefix="batch-member-profile-"))
    request = RunRequest(stand_file=STAND, out=out, seed=1, periods=periods, stored_response=False)
    choices = [MemberChoice(p, f"S-{p}") for p in positions]
    start = time.perf_counter()
    execute_batch(request, choices, config=stand_config.load(STAND))
    whole = time.perf_counter() - start
    others = len(positions) - 1
    per_member = spent["finish"] / others
    load = os.getloadavg()
    print(f"{len(positions)} DUTs, {periods} periods, unpaced (load average {load[0]:.2f})")
    print(f"batch run wall {whole:.2f} s; members after the first: {per_member:.2f} s each")
    print(f"per member / whole run: {per_member / whole:.3f}")
    print(f"recordings read after the run: {len(reads)} for {others} members")
    if args.top:
        text = io.StringIO()
        pstats.Stats(profile, stream=text).sort_stats("cumulative").print_stats(args.top)
        print(text.getvalue())
    return 0


if __name__ == "__main__":
    sys.exit(main())
