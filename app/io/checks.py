"""Input files checked before they are read: a regular file, no larger than its format can hold.

`analyze /dev/zero` would read until the memory is gone and a FIFO blocks forever; a folder
where a file is expected gives an unhelpful error. Every file this program reads as input
(recordings, stand files, budgets, sweep summaries) passes `check_input_file` first, which
looks only at the file's metadata (`os.stat`, following links) and never opens it.
"""

from __future__ import annotations

import logging
import os
import stat
from pathlib import Path

from app.errors import Refusal

log = logging.getLogger(__name__)

MIB = 1 << 20

# Samples per channel a recording may hold: 2**25 (about 2800 periods of the piezo plan's
# 12000 samples; 256 MiB per channel as float64), so that reading one never exhausts memory.
MAX_RECORDING_SAMPLES = 1 << 25
# A CSV row is at most three numbers of ~25 characters and two separators: 80 bytes is ample.
MAX_CSV_ROW_BYTES = 80
# The CSV parser reads blocks of text straight into float64 columns (about 1.1x the samples'
# memory at its peak), so a CSV may hold as many rows as a recording samples (2.5 GiB of text).
MAX_CSV_ROWS = MAX_RECORDING_SAMPLES
MAX_CSV_BYTES = MAX_CSV_ROWS * MAX_CSV_ROW_BYTES
# HDF5: the signals (up to three channels of MAX_RECORDING_SAMPLES float64) plus metadata.
MAX_HDF5_BYTES = 3 * 8 * MAX_RECORDING_SAMPLES + 64 * MIB
# TDMS (app.io.tdms): the channels (up to three of MAX_RECORDING_SAMPLES float64; each channel
# is checked against it before its data is read) plus metadata, as for HDF5.
MAX_TDMS_BYTES = 3 * 8 * MAX_RECORDING_SAMPLES + 64 * MIB
# Text configuration (stand.toml, a budget, a sweep summary): far more than any real one.
MAX_TEXT_BYTES = 4 * MIB


class InputFileError(Refusal):
    """An input that must not be read; the message names the file and why."""


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def check_input_file(path: str | Path, max_bytes: int, what: str = "file") -> int:
    """Refuse (InputFileError) anything at `path` but an existing regular file of at most
    `max_bytes`; returns its size. Nothing is opened, so a FIFO or device cannot block."""
    path = Path(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise InputFileError(f"{path}: no such file") from None
    except OSError as exc:
        raise InputFileError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(info.st_mode):
        raise InputFileError(f"{path}: is {_kind(info.st_mode)}; a {what} must be a regular file")
    if info.st_size > max_bytes:
        raise InputFileError(
            f"{path}: {info.st_size} bytes is more than a {what} can hold ({max_bytes} bytes)"
        )
    log.debug("input %s: %d bytes", path, info.st_size)
    return info.st_size


def check_dataset_size(samples: int, where: str) -> None:
    """Refuse a recording's dataset with more samples than a recording may hold."""
    if samples > MAX_RECORDING_SAMPLES:
        raise InputFileError(
            f"{where}: {samples} samples is more than a recording may hold "
            f"({MAX_RECORDING_SAMPLES} per channel)"
        )
