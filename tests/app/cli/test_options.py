"""Choice lists live in one place each; the CLI offers exactly those (issue 14 point 8)."""

from __future__ import annotations

import argparse

import pytest

from app.cli import build_parser
from app.procedure import MODES, RunSettings
from dsp.multisine import PRESETS
from dsp.spectral import ESTIMATORS
from sim.models import DUT_CATALOGUE, PLAN_PRESET_BY_DUT, plan_preset_for
from sim.stand import FAULT_KINDS, Fault


def subcommand(name: str) -> argparse.ArgumentParser:
    parser = build_parser()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action.choices[name]
    raise AssertionError("no subcommands")


def option(command: str, flag: str) -> argparse.Action:
    for action in subcommand(command)._actions:
        if flag in action.option_strings:
            return action
    raise AssertionError(f"{command} has no {flag}")


@pytest.mark.parametrize(
    ("command", "flag", "source"),
    [
        ("run", "--estimator", ESTIMATORS),
        ("analyze", "--estimator", ESTIMATORS),
        ("run", "--mode", MODES),
        ("run", "--preset", tuple(sorted(PRESETS))),
        ("plan", "--preset", tuple(sorted(PRESETS))),
    ],
)
def test_cli_choices_are_the_source_lists(command, flag, source):
    assert tuple(option(command, flag).choices) == tuple(source)


@pytest.mark.parametrize("command", ["run", "simulate"])
def test_cli_dut_accepts_exactly_the_catalogue(command):
    action = option(command, "--dut")
    for name in DUT_CATALOGUE:
        assert action.type(name) == name
    with pytest.raises(argparse.ArgumentTypeError):
        action.type("no-such-dut")


@pytest.mark.parametrize("command", ["run", "simulate"])
def test_cli_fault_help_names_every_fault_kind(command):
    assert all(kind in option(command, "--fault").help for kind in FAULT_KINDS)
    assert all(Fault(kind, 1.0).kind == kind for kind in FAULT_KINDS)


def test_dut_presets_name_catalogue_duts_and_existing_plans():
    assert set(PLAN_PRESET_BY_DUT) <= set(DUT_CATALOGUE)
    assert all(plan_preset_for(name) in PRESETS for name in DUT_CATALOGUE)


def test_settings_accept_exactly_the_modes():
    for mode in MODES:
        assert RunSettings(mode=mode).mode == mode
    with pytest.raises(ValueError, match="mode"):
        RunSettings(mode="swept-sine")
