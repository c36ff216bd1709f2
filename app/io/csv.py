"""CSV import: a recording from two columns (reference, DUT) or three (plus drive) in volts.

One optional header line; the plan comes from options. Lines starting with '#' before the data
are comments; one of the form `# skew_s = 2e-06` gives the inter-channel delay in s, positive
when the DUT channel is sampled after the reference (the --skew option's sign; the two must
agree when both are given). A malformed file is refused with a RecordingError naming the file,
the line or channel and the problem (app.io.hdf5.validate).

The numbers are converted by pyarrow's C CSV reader (correctly rounded, as Python's float());
a file it refuses is read again line by line, which names the offending line.
"""

from __future__ import annotations

import io
import math
import os
import re
import warnings
from pathlib import Path
from typing import BinaryIO

import numpy as np

from app.io.checks import MAX_CSV_BYTES, MAX_RECORDING_SAMPLES, InputFileError, check_input_file
from app.io.hdf5 import CHANNELS, Recording, RecordingError, merge_skew, validate
from dsp.calibration import ReferenceChain
from dsp.multisine import Plan
from dsp.uncertainty import Budget

SKEW_LINE = re.compile(r"^#\s*skew_s\s*=\s*(\S+)\s*$")
CSV_BLOCK_BYTES = 1 << 20  # text parsed at a time, bytes (a block ends at a line end)
ARROW_BLOCK_BYTES = 1 << 20  # text pyarrow's reader converts at a time, bytes
# Line breaks str.splitlines knows besides \n and \r\n (ASCII ones; the others are not ASCII):
# a block holding one is parsed line by line, so line numbers stay those of the text (and of
# earlier versions). Searched byte by byte (memchr): a regular expression costs more than
# parsing the numbers.
_OTHER_BREAKS = (b"\x0b", b"\x0c", b"\x1c", b"\x1d", b"\x1e")


def _other_breaks(text: bytes) -> bool:
    """Whether `text` holds a line break other than \\n and \\r\\n (see _OTHER_BREAKS)."""
    if b"\r" in text and text.count(b"\r") != text.count(b"\r\n"):
        return True
    return any(mark in text for mark in _OTHER_BREAKS)


def _parse_csv(handle: BinaryIO, name: str) -> tuple[list[np.ndarray], float | None]:
    """The columns (float64 V) of the CSV open in `handle` (binary) and the skew (s) of a
    '# skew_s = ...' comment line, None without one."""
    number = 0  # lines consumed
    skew_s = None
    while True:  # leading comment lines, then one optional header line
        offset = handle.tell()
        raw = handle.readline()
        if not raw:
            break
        if _other_breaks(raw):  # lines end with \r alone (or worse): the text whole
            handle.seek(0)
            return _parse_text(handle.read().decode("utf-8").splitlines(), name)
        line = raw.decode("utf-8").rstrip("\r\n")
        if line.lstrip().startswith("#"):
            number += 1
            skew_s = _skew_line(line, number, name, skew_s)
            continue
        if _is_numeric_row(line):
            handle.seek(offset)  # the first data line
        else:
            number += 1  # one header line allowed
        break
    capacity = _count_lines(handle)  # rows at most: columns allocated once, filled in place
    fast = _arrow_columns(handle, capacity)
    if fast is not None:
        return fast, skew_s
    columns: list[np.ndarray] = []
    width: int | None = None
    rows = 0
    while block := handle.read(CSV_BLOCK_BYTES):
        if not block.endswith(b"\n"):
            block += handle.readline()
        data = _fast_block(block, width)
        lines = block.count(b"\n") + (not block.endswith(b"\n"))
        if data is None:
            text_lines = block.decode("utf-8").splitlines()
            data = _parse_lines(text_lines, number, width, name)
            lines = len(text_lines)
        number += lines
        if rows + data.shape[0] > MAX_RECORDING_SAMPLES:
            raise RecordingError(
                f"{name}: line {number}: more than {MAX_RECORDING_SAMPLES} rows, more than a "
                "recording may hold"
            )
        if data.shape[0]:
            width = data.shape[1]
            if rows + data.shape[0] > capacity:  # more lines than \n counted (other breaks)
                capacity = max(2 * capacity, rows + data.shape[0])
                columns = [_grown(c, capacity) for c in columns]
            if not columns:
                columns = [np.empty(capacity) for _ in range(width)]
            for column, values in zip(columns, data.T, strict=True):
                column[rows : rows + data.shape[0]] = values
            rows += data.shape[0]
    if not rows:
        raise RecordingError(f"{name}: no data rows")
    if capacity - rows > rows // 64:  # many blank lines: no idle tail kept
        return [c[:rows].copy() for c in columns], skew_s
    return [c[:rows] for c in columns], skew_s


def _arrow_columns(handle: BinaryIO, capacity: int) -> list[np.ndarray] | None:
    """The data rows from the handle's position as float64 columns (V), converted by pyarrow's
    C reader into columns of `capacity` samples allocated once; None (the handle back at its
    position) when the reader refuses anything: a cell that is not a number in its syntax (an
    empty item, a word, a quote, a line break other than \n, \r\n or \r, a non-ASCII
    digit), a row of another width, not 2 or 3 columns, more rows than `capacity` or than a
    recording may hold. The line-by-line parser then decides, with its messages; what the
    reader accepts, float() reads as the same numbers."""
    import pyarrow as pa
    import pyarrow.csv as pa_csv

    start = handle.tell()
    if capacity > MAX_RECORDING_SAMPLES:
        return None
    first = handle.read(4096)
    handle.seek(start)
    line = first.split(b"\n", 1)[0]
    delimiter = ";" if b";" in line and b"," not in line else ","
    columns: list[np.ndarray] = []
    rows = 0
    source = _native(handle, start)
    try:
        reader = pa_csv.open_csv(
            source,
            read_options=pa_csv.ReadOptions(
                autogenerate_column_names=True, block_size=ARROW_BLOCK_BYTES
            ),
            parse_options=pa_csv.ParseOptions(delimiter=delimiter, quote_char=False),
            convert_options=pa_csv.ConvertOptions(
                column_types={f"f{i}": pa.float64() for i in range(3)},
                null_values=[],
                strings_can_be_null=False,
            ),
        )
        width = len(reader.schema)
        if width not in (2, 3):
            raise ValueError(f"{width} columns")
        columns = [np.empty(capacity) for _ in range(width)]
        for batch in reader:
            n = batch.num_rows
            if rows + n > capacity:  # lone \r line ends: the line-by-line parser counts
                raise ValueError("more rows than lines")
            for column, values in zip(columns, batch.columns, strict=True):
                column[rows : rows + n] = values.to_numpy(zero_copy_only=False)
            rows += n
    except (pa.ArrowException, ValueError):
        handle.seek(start)
        return None
    finally:
        if source is not handle:
            source.close()  # type: ignore[attr-defined]
    if not rows:
        handle.seek(start)
        return None
    if capacity - rows > rows // 64:  # many blank lines: no idle tail kept
        return [c[:rows].copy() for c in columns]
    return [c[:rows] for c in columns]


def _native(handle: BinaryIO, start: int) -> object:
    """The open file as pyarrow reads it fastest and outside Python's heap: the same file
    (the same inode, reopened through /proc/self/fd, so not a name an attacker could swap)
    at `start`; the handle itself where there is no such path."""
    import pyarrow as pa

    try:
        fd = handle.fileno()
        fd_path = f"/proc/self/fd/{fd}"
        same = os.path.exists(fd_path) and os.stat(fd_path).st_ino == os.fstat(fd).st_ino
    except (OSError, AttributeError, io.UnsupportedOperation):
        same = False
    if not same:
        return handle
    native = pa.OSFile(fd_path)
    native.seek(start)
    return native


def _count_lines(handle: BinaryIO) -> int:
    """Lines from the handle's position to the end (\\n counted, plus a last one without it),
    at most MAX_RECORDING_SAMPLES + 1; the position is kept."""
    start = handle.tell()
    count = 1
    while (piece := handle.read(CSV_BLOCK_BYTES)) and count <= MAX_RECORDING_SAMPLES:
        count += piece.count(b"\n")
    handle.seek(start)
    return min(count, MAX_RECORDING_SAMPLES + 1)


def _grown(column: np.ndarray, capacity: int) -> np.ndarray:
    """`column` copied into a longer array of `capacity` samples."""
    longer = np.empty(capacity)
    longer[: column.size] = column
    return longer


def _parse_text(lines: list[str], name: str) -> tuple[list[np.ndarray], float | None]:
    """_parse_csv for text split into lines up front (line breaks other than \\n, \\r\\n)."""
    start = 0
    skew_s = None
    while start < len(lines) and lines[start].lstrip().startswith("#"):
        skew_s = _skew_line(lines[start], start + 1, name, skew_s)
        start += 1
    if start < len(lines) and not _is_numeric_row(lines[start]):
        start += 1  # one header line allowed
    data = _parse_lines(lines[start:], start, None, name)
    if not data.shape[0]:
        raise RecordingError(f"{name}: no data rows")
    return [np.ascontiguousarray(column) for column in data.T], skew_s


def _skew_line(line: str, number: int, name: str, skew_s: float | None) -> float | None:
    """The skew (s) a comment line states, else `skew_s`; RecordingError naming the line when
    it is not a delay."""
    match = SKEW_LINE.match(line.strip())
    if not match:
        return skew_s
    try:
        value = float(match.group(1))
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and abs(value) <= 1.0):
        raise RecordingError(
            f"{name}: line {number}: skew_s {match.group(1)!r} is not a delay in s "
            "(finite, within +-1 s)"
        )
    return value


def _fast_block(block: bytes, width: int | None) -> np.ndarray | None:
    """A block of whole lines as (rows, columns) float64 by numpy's C reader; None when it
    holds anything but well-formed rows of 2 or 3 numbers (`width` when known), a byte that
    is not ASCII, or another line break than \\n or \\r\\n (the line-by-line parser then
    decides, with the messages and line numbers it always gave)."""
    if not block.isascii() or _other_breaks(block):
        return None
    if b";" in block:
        block = block.replace(b";", b",")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # "input contained no data": an empty block
            data = np.loadtxt(
                io.BytesIO(block),
                delimiter=",",
                dtype=np.float64,
                comments=None,
                ndmin=2,
                encoding="latin-1",  # bytes 1:1; anything not ASCII fails to convert
            )
    except (ValueError, UserWarning):
        return None
    if data.shape[1] not in (2, 3) or (width is not None and data.shape[1] != width):
        return None
    return data


def _parse_lines(lines: list[str], before: int, width: int | None, name: str) -> np.ndarray:
    """Rows of `lines` (the first is line `before` + 1) as (rows, columns) float64, blank lines
    skipped; RecordingError naming the line of a wrong column count or a non-number."""
    rows: list[list[float]] = []
    for number, raw in enumerate(lines, start=before + 1):
        if not raw.strip():
            continue
        cells = [c.strip() for c in raw.replace(";", ",").split(",")]
        if width is None:
            width = len(cells)
            if width not in (2, 3):
                raise RecordingError(
                    f"{name}: line {number}: {width} columns; expected 2 (reference, DUT) "
                    "or 3 (reference, DUT, drive) in volts"
                )
        elif len(cells) != width:
            raise RecordingError(
                f"{name}: line {number}: {len(cells)} columns where earlier lines have {width}"
            )
        try:
            rows.append([float(c) for c in cells])
        except ValueError:
            raise RecordingError(
                f"{name}: line {number}: not a number in {raw.strip()!r}"
            ) from None
    return np.asarray(rows, dtype=np.float64).reshape(len(rows), width or 0)


def _is_numeric_row(line: str) -> bool:
    try:
        [float(c) for c in line.replace(";", ",").split(",")]
    except ValueError:
        return False
    return True


def read_csv(
    path: str | Path,
    plan: Plan,
    chain: ReferenceChain,
    budget: Budget,
    *,
    settle_periods: int = 0,
    range_v: float | None = None,
) -> Recording:
    """Read a CSV of two (reference, DUT) or three (+ drive) columns in volts and validate it.

    The lines are counted first; float64 columns of that length are filled in place from
    blocks of about `CSV_BLOCK_BYTES` of text parsed by numpy's C reader, so the peak memory
    stays about 1.1x the samples' (issue 16 point 7). A block the fast reader refuses is
    parsed line by line, which names the offending line."""
    path = Path(path)
    name = path.name
    try:
        check_input_file(path, MAX_CSV_BYTES, "CSV recording")
    except InputFileError as exc:
        raise RecordingError(str(exc)) from None
    try:
        handle = open(path, "rb")
    except FileNotFoundError:
        raise RecordingError(f"{path}: no such file") from None
    except OSError as exc:
        raise RecordingError(f"{name}: cannot be read as text ({exc})") from None
    try:
        with handle:
            columns, header_skew_s = _parse_csv(handle, name)
    except UnicodeDecodeError as exc:
        raise RecordingError(f"{name}: cannot be read as text ({exc})") from None
    except OSError as exc:
        raise RecordingError(f"{name}: cannot be read as text ({exc})") from None
    chain = merge_skew(chain, header_skew_s, name, "the file's 'skew_s = {:g}' line")
    ranges = {} if range_v is None else {c: float(range_v) for c in CHANNELS}
    recording = Recording(
        sample_rate_hz=plan.sample_rate_hz,
        period_samples=plan.period_samples,
        reference_v=columns[0],
        dut_v=columns[1],
        drive_v=columns[2] if len(columns) == 3 else None,
        plan=plan,
        chain=chain,
        budget=budget,
        settle_periods=settle_periods,
        ranges_v=ranges,
        source=str(path),
    )
    validate(recording, name)
    return recording
