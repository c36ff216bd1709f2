"""`accelcal devices` and `accelcal gui`: what hardware is found; the technician's window."""

from __future__ import annotations

import argparse

from app.cli.exits import EXIT_FAILURE, EXIT_OK, UsageError
from app.cli.options import sim_hum_option, writable_folder
from hardware.errors import HardwareError


def cmd_devices(args: argparse.Namespace) -> int:
    from hardware.discovery import describe, list_ni_devices

    print(describe())
    try:
        return EXIT_OK if list_ni_devices() else EXIT_FAILURE
    except HardwareError:
        return EXIT_FAILURE  # no NI-DAQmx driver (said above)


def cmd_gui(args: argparse.Namespace) -> int:
    if args.sim and args.stand:
        raise UsageError("--sim and --stand: choose one")
    writable_folder(args.out, "--out")
    from app.gui import run_gui  # Qt only once the options are good

    return run_gui(
        stand_file=args.stand,
        out=args.out,
        paced=not args.unpaced,
        seed=args.seed,
        autorun=args.autorun,
        screenshot=args.screenshot,
        quit_after_run=args.quit_after_run,
        dut=args.dut,
        sim=args.sim,
        db=args.db,
        sim_hum=sim_hum_option(args.sim_hum),
    )
