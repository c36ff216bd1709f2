"""app.io.checks: only regular files, no larger than their format can hold, never opened first."""

from __future__ import annotations

import os

import h5py
import numpy as np
import pytest

from app.io import checks as input_files
from app.io import csv as csv_import
from app.io.checks import InputFileError, check_input_file
from app.io.csv import read_csv
from app.io.hdf5 import RecordingError, read_recording, write_recording
from dsp.calibration import ReferenceChain
from dsp.crestfactor import schroeder_phases
from dsp.multisine import make_plan
from dsp.uncertainty import Budget
from tests.synthetic import lowpass_response, make_recording

# Schroeder's phases: no optimisation while the tests are collected (the phases do not matter here)
PLAN = make_plan(
    [10.0, 40.0, 160.0, 630.0],
    6000,
    12000,
    5.0,
    160.0,
    phases_rad=list(schroeder_phases(np.ones(4))),
)


def test_a_regular_file_within_the_cap_passes(tmp_path):
    path = tmp_path / "a.csv"
    path.write_text("1,2\n")
    assert check_input_file(path, 4) == 4


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p: p.mkdir(), "is a folder"),
        (lambda p: os.mkfifo(p), "is a FIFO (named pipe)"),
        (lambda p: p.symlink_to("/dev/zero"), "is a character device"),
        (lambda p: p.write_text("12345"), "5 bytes is more than a recording can hold (4 bytes)"),
        (lambda p: None, "no such file"),
    ],
)
def test_anything_else_is_refused_naming_the_file(tmp_path, make, message):
    path = tmp_path / "x.csv"
    make(path)
    with pytest.raises(InputFileError) as info:
        check_input_file(path, 4, "recording")
    assert str(info.value).startswith(f"{path}: ") and message in str(info.value)


def test_a_csv_larger_than_the_cap_is_refused_before_reading(tmp_path, monkeypatch):
    path = tmp_path / "big.csv"
    path.write_text("0.1,0.2\n" * 100)
    monkeypatch.setattr(csv_import, "MAX_CSV_BYTES", 100)
    chain = ReferenceChain.flat(1.0)
    with pytest.raises(RecordingError, match=r"800 bytes is more than a CSV recording can hold"):
        read_csv(path, PLAN, chain, Budget(()))


def test_an_hdf5_dataset_over_the_sample_cap_is_refused_before_reading(tmp_path, monkeypatch):
    path = tmp_path / "rec.h5"
    write_recording(path, make_recording(PLAN, lowpass_response(), periods=2))
    monkeypatch.setattr(input_files, "MAX_RECORDING_SAMPLES", 12000)
    with pytest.raises(RecordingError, match=r"/signals/reference: 24000 samples is more than"):
        read_recording(path)


@pytest.mark.parametrize(
    ("dataset", "dtype"),
    [("signals/reference", np.int16), ("signals/dut", np.int64), ("truth/phase_deg", np.int32)],
)
def test_an_hdf5_dataset_of_another_type_than_float_is_refused_by_name(tmp_path, dataset, dtype):
    path = tmp_path / "rec.h5"
    write_recording(path, make_recording(PLAN, lowpass_response(), periods=2))
    with h5py.File(path, "r+") as f:
        if dataset not in f:  # a recording of the simulator carries /truth
            f.create_dataset("truth/frequency_hz", data=np.array([10.0]))
            f.create_dataset("truth/sensitivity_mv_per_ms2", data=np.array([1.0]))
            f.create_dataset(dataset, data=np.array([0.0]))
        data = f[dataset][()]
        del f[dataset]
        f.create_dataset(dataset, data=np.round(data * 100).astype(dtype))
    with pytest.raises(RecordingError) as info:
        read_recording(path)
    assert f"/{dataset}: dataset of type {np.dtype(dtype)}, expected floating point" in str(
        info.value
    )
