"""Safe failure on every path (issue 12, points 3-6): every fault kind, a full disk, SIGHUP and
SIGTERM end a run aborted with the drive at 0 V, the power amplifier off, a readable recording
and a valid manifest; the drive limit holds in every phase; Ctrl-C before a run exits 130."""

from __future__ import annotations

import dataclasses
import errno
import itertools
import json
import math
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

import app.procedure as procedure_module
import app.procedure.stand_io as gate_module
from app.cli import main
from app.io.hdf5 import DiskFullError, RecordingWriter, read_recording
from app.procedure import PeriodBlock, Procedure, RunSettings, State, StateChanged
from app.procedure.phase_store import stored_phases
from app.records.run_folder import RunFolder, inspect_run, load_run
from app.records.run_record import RunRecord
from app.stand import config as stand_config
from app.stand.open import open_stand
from dsp.multisine import make_plan, preset_plan
from sim.models import ExciterModel, StandModel
from sim.stand import FAULT_KINDS, Fault

CONFIG = stand_config.load()
ROOT = Path(__file__).resolve().parents[3]
FAULT_AT_S = 9.0  # into the identification/equalisation: the shaker is moving


def env() -> dict[str, str]:
    """The environment of a CLI subprocess: this checkout's packages first."""
    return {**os.environ, "PYTHONPATH": str(ROOT)}


def assert_survived(folder: Path, reason: str, *, power_lost: bool = False) -> RunRecord:
    """Aborted with `reason` in its status, drive at 0 V, power amplifier off (or its loss
    logged), recording readable and marked aborted, manifest valid."""
    record = load_run(folder)  # verifies the manifest first (RunIntegrityError otherwise)
    assert inspect_run(folder).state == "aborted"
    assert record.status == "aborted" and reason in record.abort_reason
    assert record.final_output_v == 0.0
    with h5py.File(folder / "recording.h5", "r") as f:  # plain HDF5 opens it
        assert f["signals/reference"].shape[0] > 0
    recording = read_recording(folder / "recording.h5")
    assert recording.status == "aborted" and recording.periods >= 2
    log = (folder / "run.log").read_text()
    assert "power amplifier: output on" in log  # every case here ends a moving run
    if power_lost:  # nobody can switch a lost amplifier off: said, not hidden
        assert "power amplifier: output could not be switched off" in log
    else:
        assert log.index("power amplifier: output off") > log.index("power amplifier: output on")
    return record


def only_run(out: Path) -> Path:
    (folder,) = [p for p in out.iterdir() if p.is_dir()]
    return folder


# --- every fault kind -----------------------------------------------------------------------

EXPECTED = {
    "daq-timeout": "DaqTimeoutError",
    "device-lost": "DeviceLostError",
    "visa-timeout": "VisaTimeoutError",
    "amplifier-fault": "Over-temperature",
    "overload": "OverloadError",
    "over-current": "Over-current",
    "interlock": "interlock open",
    "amplifier-lost": "power amplifier at ASRL1::INSTR: connection lost",
}


def test_every_fault_kind_of_the_simulator_is_covered():
    assert set(EXPECTED) == set(FAULT_KINDS)


@pytest.mark.parametrize("kind", FAULT_KINDS)
def test_every_fault_kind_exits_3_at_0_v_readable_and_verified(tmp_path, capsys, kind):
    out = tmp_path / "runs"
    code = main(["run", "--sim", "--fault", f"{kind}@{FAULT_AT_S}", "--out", str(out), "--json"])
    assert code == 3
    record = json.loads(capsys.readouterr().out)
    assert record["status"] == "aborted"
    assert_survived(only_run(out), EXPECTED[kind], power_lost=kind == "amplifier-lost")


# --- the power amplifier --------------------------------------------------------------------


def test_power_amplifier_is_on_only_while_the_run_plays(tmp_path):
    stand = open_stand(CONFIG, dut="piezo")
    assert stand.power_amplifier is not None and stand.daq.power_output_on is False
    states = []

    def listener(event):
        if isinstance(event, PeriodBlock):
            states.append((event.state, stand.daq.power_output_on))

    folder = RunFolder.create(tmp_path, "pa")
    settings = RunSettings(periods=3)
    try:
        finished = Procedure(
            stand, preset_plan("piezo", optimiser=stored_phases), settings, folder, listener
        ).run()
        assert finished.status == "complete"
        assert stand.daq.power_output_on is False  # switched off by the run itself
    finally:
        stand.close()
    assert states and all(on for _, on in states)  # on for every period played


@pytest.mark.parametrize(
    ("kind", "expected"),
    [
        ("over-current", "Over-current (fault code 3)"),
        ("interlock", "interlock open"),
        ("amplifier-fault", "Over-temperature"),
    ],
)
def test_amplifier_faults_come_through_the_amplifier_and_leave_it_off(tmp_path, kind, expected):
    stand = open_stand(CONFIG, dut="piezo", faults=(Fault(kind, FAULT_AT_S),))
    folder = RunFolder.create(tmp_path, kind)
    try:
        finished = Procedure(
            stand, preset_plan("piezo", optimiser=stored_phases), RunSettings(), folder
        ).run()
        assert stand.daq.power_output_on is False
    finally:
        stand.close()
    assert finished.status == "aborted" and "AmplifierFaultError" in finished.abort_reason
    assert expected in finished.abort_reason
    assert stand.daq.output_v == 0.0 and stand.daq.output.stopped
    # the DAQ drive faded out after the fault (no step to 0 V at the fault's period)
    assert "state: fading out" in (folder.path / "run.log").read_text()


def test_power_amplifier_faults_need_a_power_amplifier():
    config = dataclasses.replace(CONFIG, power_amplifier=None)
    with pytest.raises(stand_config.ConfigError, match="over-current: the stand has no power"):
        open_stand(config, faults=(Fault("over-current", 1.0),))


def test_natural_over_travel_opens_the_interlock_and_ends_the_run(tmp_path):
    limits = dataclasses.replace(CONFIG.limits, displacement_peak_to_peak_m=1.0)
    config = dataclasses.replace(CONFIG, limits=limits)  # preflight lets it through ...
    short = StandModel(  # ... onto an exciter with 4 mm stroke: the plan needs 5.3 mm p-p
        reference_gain=CONFIG.reference.gain,
        skew_s=CONFIG.skew_s,
        exciter=ExciterModel(stroke_peak_to_peak_m=4e-3),
    )
    stand = open_stand(config, dut="piezo", model=short)
    folder = RunFolder.create(tmp_path, "travel")
    try:
        finished = Procedure(
            stand, preset_plan("piezo", optimiser=stored_phases), RunSettings(), folder
        ).run()
        assert stand.daq.power_output_on is False
    finally:
        stand.close()
    assert finished.status == "aborted" and "interlock open" in finished.abort_reason
    assert stand.daq.output_v == 0.0


# --- the drive limit ------------------------------------------------------------------------


def small_plan():
    piezo = preset_plan("piezo", optimiser=stored_phases)
    return make_plan((80.0, 160.0, 315.0), piezo.sample_rate_hz, piezo.period_samples, 5.0, 160.0)


@pytest.mark.parametrize("mode", ["multisine", "stepped-sine"])
def test_every_written_period_passes_the_drive_limit_gate(tmp_path, monkeypatch, mode):
    gated = []
    gate = procedure_module.limited_drive

    def spy(period_v, limit_v):
        gated.append(float(np.max(np.abs(period_v))))
        return gate(period_v, limit_v)

    monkeypatch.setattr(gate_module, "limited_drive", spy)  # where the gate lives
    stand = open_stand(CONFIG, dut="piezo")
    folder = RunFolder.create(tmp_path, mode)
    settings = RunSettings(periods=3, mode=mode)
    try:
        finished = Procedure(stand, small_plan(), settings, folder).run()
    finally:
        stand.close()
    assert finished.status == "complete"
    written = stand.daq.output.written_peaks_v
    # start, identification, crossfades, equalisation, fade: each one through the gate
    assert len(written) > 6 and gated == written


@pytest.mark.parametrize("mode", ["multisine", "stepped-sine"])
def test_no_sample_over_a_low_drive_limit_is_ever_written(tmp_path, mode):
    limit_v = 5e-3  # the piezo plan's identification drive peaks at 8.85 mV
    limits = dataclasses.replace(CONFIG.limits, drive_peak_v=limit_v)
    stand = open_stand(dataclasses.replace(CONFIG, limits=limits), dut="piezo")
    folder = RunFolder.create(tmp_path, mode)
    plan = preset_plan("piezo", optimiser=stored_phases) if mode == "multisine" else small_plan()
    try:
        finished = Procedure(stand, plan, RunSettings(mode=mode), folder).run()
    finally:
        stand.close()
    assert finished.status == "aborted"
    assert "drive limit" in finished.abort_reason or "limit" in finished.abort_reason
    written = stand.daq.output.written_peaks_v
    assert written and max(written) <= limit_v
    assert max(p.peak_v for p in stand.daq.output.periods) <= limit_v
    assert stand.daq.output_v == 0.0


def test_the_gate_refuses_over_the_limit_and_non_finite():
    ok = procedure_module.limited_drive(np.array([0.1, -0.2]), 0.2)
    assert ok.dtype == float
    with pytest.raises(procedure_module.DriveLimitError, match=r"0\.2001 V exceeds"):
        procedure_module.limited_drive(np.array([0.1, -0.2001]), 0.2)
    with pytest.raises(procedure_module.DriveLimitError):
        procedure_module.limited_drive(np.array([0.0, np.nan]), 0.2)


# --- full disk ------------------------------------------------------------------------------


def test_recording_stops_before_the_disk_is_full_and_stays_readable(tmp_path, monkeypatch):
    plan = preset_plan("piezo", optimiser=stored_phases)
    stand = open_stand(CONFIG, dut="piezo")
    path = tmp_path / "r.h5"
    writer = RecordingWriter(path, plan, stand.chain, stand.budget, with_drive=True)
    n = plan.period_samples
    x = 0.1 * np.random.default_rng(1).standard_normal((3, n))
    writer.append(*x)
    monkeypatch.setattr("app.io.hdf5.free_bytes", lambda p: 3 * 8 * n * 2.0)
    with pytest.raises(DiskFullError, match=r"MB left for r\.h5") as caught:
        writer.append(*x)
    assert caught.value.errno == errno.ENOSPC
    assert writer.set_status("aborted", "disk full")
    writer.close()
    stand.close()
    recording = read_recording(path)
    assert recording.periods == 1 and recording.status == "aborted"


def test_an_enospc_from_hdf5_is_a_disk_full_error(tmp_path):
    plan = preset_plan("piezo", optimiser=stored_phases)
    stand = open_stand(CONFIG, dut="piezo")
    writer = RecordingWriter(tmp_path / "r.h5", plan, stand.chain, stand.budget)
    stand.close()
    real = writer._file

    class Full:  # what h5py raises when the disk refuses a flush
        def flush(self):
            raise OSError("Can't write data (file write failed: errno = 28, error message = ..)")

    writer._file = Full()
    n = plan.period_samples
    with pytest.raises(DiskFullError, match="errno = 28"):
        writer.append(np.ones(n), np.ones(n))
    writer._file = real
    writer.close()


@pytest.mark.parametrize("full_in", [State.IDENTIFYING, State.EQUALISING])
def test_a_disk_full_during_a_crossfade_fades_out_from_where_it_ends(
    tmp_path, monkeypatch, full_in
):
    """The disk fills while a crossfade plays: the run fades out from the crossfade's end, so
    the drive never steps at a period boundary and the last period played ends near 0 V."""
    full = {"now": False}
    monkeypatch.setattr("app.io.hdf5.free_bytes", lambda p: 0.0 if full["now"] else math.inf)
    stand = open_stand(CONFIG, dut="piezo", systematic=False)
    folder = RunFolder.create(tmp_path, "full")

    def listener(event):
        if isinstance(event, StateChanged) and event.state == full_in:
            full["now"] = True  # the crossfade into this state is the next period recorded

    try:
        finished = Procedure(
            stand, preset_plan("piezo", optimiser=stored_phases), RunSettings(), folder, listener
        ).run()
    finally:
        stand.close()
    assert finished.status == "aborted" and finished.abort_reason.startswith("disk full")
    played = stand.daq.output.periods
    peak = max(p.peak_v for p in played)
    assert played[-1].tail_rms_v <= 0.01 * peak  # faded out before the stop
    for before, after in itertools.pairwise(played):
        tail, head = before.tail_rms_v, after.head_rms_v
        assert head <= 5 * tail + 0.01 * after.peak_v, (before, after)
        assert tail <= 5 * head + 0.01 * before.peak_v, (before, after)
    assert read_recording(folder.recording).status == "aborted"


def _file_size_limit(limit_bytes: int):
    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))

    return apply


def test_file_size_limit_ends_the_run_aborted_disk_full_exit_3(tmp_path):
    out = tmp_path / "runs"
    process = subprocess.run(
        [sys.executable, "-m", "app", "run", "--sim", "--out", str(out), "--json"],
        preexec_fn=_file_size_limit(2_000_000),  # the recording reaches it in identification
        capture_output=True,
        text=True,
        env=env(),
        timeout=300,
    )
    assert process.returncode == 3, process.stderr
    assert "Traceback" not in process.stderr
    record = json.loads(process.stdout)
    assert record["abort_reason"].startswith("disk full")
    folder = only_run(out)
    assert_survived(folder, "disk full")
    assert "state: fading out" in (folder / "run.log").read_text()  # from the drive playing


def test_a_tiny_file_size_limit_is_one_line_not_a_kill(tmp_path):
    """SIGXFSZ is ignored: writing past RLIMIT_FSIZE is an EFBIG error, not a killed process."""
    process = subprocess.run(
        [sys.executable, "-m", "app", "run", "--sim", "--out", str(tmp_path / "runs")],
        preexec_fn=_file_size_limit(10_000),  # config.json (14 kB) does not fit
        capture_output=True,
        text=True,
        env=env(),
        timeout=300,
    )
    assert process.returncode == 3, process.stderr
    assert "Traceback" not in process.stderr
    (line,) = process.stderr.strip().splitlines()
    assert "not started, nothing moved" in line and "File too large" in line


def test_results_that_cannot_be_stored_give_one_line_and_exit_3(tmp_path, capsys, monkeypatch):
    def refuse(self, record, results):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(RunFolder, "finish", refuse)
    out = tmp_path / "runs"
    assert main(["run", "--sim", "--fault", "device-lost@5", "--out", str(out), "--json"]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "could not be stored (No space left on device)" in err[0]
    assert "drive at 0 V" in err[0] and "aborted" in err[0]


# --- signals --------------------------------------------------------------------------------


def _log_text(out: Path) -> str:
    return "".join(p.read_text() for p in out.glob("*/run.log"))


@pytest.mark.long
@pytest.mark.parametrize("signum", [signal.SIGHUP, signal.SIGTERM], ids=["SIGHUP", "SIGTERM"])
def test_sighup_and_sigterm_fade_out_and_exit_3(tmp_path, signum):
    out = tmp_path / "runs"
    process = subprocess.Popen(
        [sys.executable, "-m", "app", "run", "--sim", "--paced", "--out", str(out), "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env(),
    )
    deadline = time.monotonic() + 120  # a condition polled, no timing assumed
    while time.monotonic() < deadline and "state: equalising" not in _log_text(out):
        time.sleep(0.1)
    process.send_signal(signum)  # the shaker is moving (identified, now equalising)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 3, stderr
    name = signal.Signals(signum).name
    folder = only_run(out)
    assert_survived(folder, f"terminated ({name})")
    assert "state: fading out" in (folder / "run.log").read_text()
    assert json.loads(stdout)["status"] == "aborted"


# Stops the interpreter inside the first import of STAGE: says so on stdout, then waits for
# the signal, so that Ctrl-C arrives at a known point of the start-up (no timing assumed).
_STOP_IN_IMPORT = """
import importlib.abc, signal, sys
STAGE = sys.argv[1]
class Stop(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == STAGE:
            sys.meta_path.remove(self)
            print("importing " + name, flush=True)
            signal.pause()
        return None
sys.meta_path.insert(0, Stop())
sys.argv[1:] = sys.argv[2:]
from app.__main__ import run
raise SystemExit(run())
"""


# issue 34: a simulated run imports no scipy.special any more (dsp.quantiles); pyvisa (the
# simulated amplifiers' VISA) is among the heavier imports left
@pytest.mark.parametrize("stage", ["numpy", "pyvisa", "h5py", "sim.stand"])
def test_ctrl_c_while_starting_exits_130_with_one_line(tmp_path, stage):
    """Ctrl-C while importing numpy, pyvisa, h5py or the stand: one line, exit 130."""
    process = subprocess.Popen(
        [sys.executable, "-c", _STOP_IN_IMPORT, stage, "run", "--sim", "--out", str(tmp_path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env(),
        # as from a terminal: a shell without job control starts background jobs (a CI
        # runner's, say) with SIGINT ignored, and a child inherits that
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert process.stdout is not None
    assert process.stdout.readline() == f"importing {stage}\n"  # it waits there for the signal
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 130, stderr
    assert "Traceback" not in stderr
    assert stderr == "accelcal: interrupted (Ctrl-C)\n"


def test_console_script_is_the_interrupt_safe_entry_point():
    text = (ROOT / "pyproject.toml").read_text()
    assert 'accelcal = "app.__main__:run"' in text


def test_free_bytes_is_the_smaller_of_the_disk_and_the_file_size_limit(tmp_path, monkeypatch):
    from app.io import hdf5 as recording

    path = tmp_path / "r.h5"
    path.write_bytes(b"x" * 1000)

    class Stat:
        f_bavail, f_frsize = 10, 4096  # 40960 bytes free on the disk

    monkeypatch.setattr(recording.os, "statvfs", lambda folder: Stat())
    unlimited = (resource.RLIM_INFINITY, resource.RLIM_INFINITY)
    monkeypatch.setattr(recording.resource, "getrlimit", lambda which: unlimited)
    assert recording.free_bytes(path) == 40960
    monkeypatch.setattr(recording.resource, "getrlimit", lambda which: (5000, 5000))
    assert recording.free_bytes(path) == 4000  # the limit minus what the file holds
