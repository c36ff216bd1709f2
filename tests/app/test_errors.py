"""One refusal base: every bad-input error of every package exits 2 through the CLI, by its
kind (a subclass of app.errors.REFUSALS), never by its module's or class's name."""

from __future__ import annotations

import argparse

import pytest

from app import cli
from app.certificate import CertificateError
from app.errors import REFUSALS, Refusal
from app.io.checks import InputFileError
from app.io.hdf5 import RecordingError
from app.procedure.errors import PreflightError, ProcedureError, RunNotRecordedError
from app.procedure.request import RequestError
from app.records.db.errors import RecordsInputError
from app.records.run_folder import RunIntegrityError
from app.stand.config import ConfigError
from dsp.calibration import AnalysisError
from dsp.errors import InputRefused as DspInputRefused
from dsp.multisine import PlanError
from dsp.segments import SegmentError
from hardware.errors import DeviceLostError
from hardware.errors import InputRefused as HardwareInputRefused
from hardware.teds import TedsError


def _exit_of(
    error: BaseException, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> tuple[int, str]:
    """The exit code and stderr of `accelcal plan` when the command raises `error`."""

    def raising(args: argparse.Namespace) -> int:
        raise error

    monkeypatch.setitem(cli.COMMANDS, "plan", raising)
    code = cli.main(["plan"])
    return code, capsys.readouterr().err


@pytest.mark.parametrize(
    "error",
    [
        cli.UsageError("--level: bad"),  # app.cli
        RequestError("--sensor: bad"),  # app.procedure
        PreflightError("level: bad"),
        RecordsInputError("--db: bad"),  # app.records
        RunIntegrityError("manifest: bad"),
        RecordingError("recording: bad"),  # app.io
        InputFileError("file: bad"),
        ConfigError("daq.device: bad"),  # app.stand
        CertificateError("customer: bad"),  # app.certificate
        PlanError("lines: bad"),  # dsp
        SegmentError("segments: bad"),
        AnalysisError("periods: bad"),
        TedsError("TEDS: bad"),  # hardware
    ],
    ids=lambda e: type(e).__name__,
)
def test_a_refusal_of_each_package_exits_2(error, monkeypatch, capsys) -> None:
    code, err = _exit_of(error, monkeypatch, capsys)
    assert (code, err) == (2, f"accelcal plan: error: {error}\n")


def test_a_new_refusal_exits_2_by_its_kind_not_its_name(monkeypatch, capsys) -> None:
    class FreshlyInvented(Refusal):
        """Defined here: no table anywhere names it."""

    class BelowApp(DspInputRefused):
        pass

    class DriverInput(HardwareInputRefused):
        pass

    for error in (FreshlyInvented("field: why"), BelowApp("x: y"), DriverInput("a: b")):
        assert _exit_of(error, monkeypatch, capsys) == (2, f"accelcal plan: error: {error}\n")


def test_a_lookalike_name_is_not_a_refusal(monkeypatch, capsys) -> None:
    # named like refusals the CLI once matched by (module, class) strings; not subclasses
    PlanError = type("PlanError", (RuntimeError,), {"__module__": "dsp.multisine"})
    ConfigError = type("ConfigError", (Exception,), {"__module__": "app.stand.config"})
    for error in (PlanError("lines"), ConfigError("daq")):
        code, err = _exit_of(error, monkeypatch, capsys)
        assert code == 1 and err.startswith("accelcal plan: failed: ")


def test_other_failures_keep_their_exit_codes(monkeypatch, capsys) -> None:
    code, err = _exit_of(DeviceLostError("cable"), monkeypatch, capsys)
    assert (code, err) == (1, "accelcal plan: DeviceLostError: cable\n")
    code, err = _exit_of(RunNotRecordedError("disk full"), monkeypatch, capsys)
    assert (code, err) == (3, "accelcal plan: disk full\n")
    # a run that could not go on is not a refusal (only PreflightError among its kind is)
    code, _ = _exit_of(ProcedureError("stand lost"), monkeypatch, capsys)
    assert code == 1


def test_every_refusal_is_a_value_error_of_one_of_three_bases() -> None:
    assert all(issubclass(base, ValueError) for base in REFUSALS)
    for kind in (PreflightError, RecordsInputError, PlanError, TedsError, cli.UsageError):
        assert issubclass(kind, REFUSALS)
    assert not issubclass(ProcedureError, REFUSALS)
