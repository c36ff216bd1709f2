"""CSV import: a recording from two columns (reference, DUT) or three (plus drive) in volts.

One optional header line; the plan comes from options. Lines starting with '#' before the data
are comments; one of the form `# skew_s = 2e-06` gives the inter-channel delay in s, positive
when the DUT channel is sampled after the reference (the --skew option's sign; the two must
agree when both are given). A malformed file is refused with a RecordingError naming the file,
the line or channel and the problem (app.io.hdf5.validate).

A several-DUT CSV (issue 36, `read_csv_channels`) names its columns in a header line:
"reference", `dut.<position>` (or `dut.<position>.<axis>`) per DUT, optionally "drive", in any
order; `# skew_s[dut.B] = 6e-06` gives one channel's skew. It gives one two-channel Recording
per DUT channel (app.io.channels). `read_csv` of a two- or three-column file is unchanged.

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

from app.io.channels import (
    MAX_IMPORT_SAMPLES,
    ImportedChannel,
    check_names,
    member_recordings,
)
from app.io.checks import MAX_CSV_BYTES, MAX_RECORDING_SAMPLES, InputFileError, check_input_file
from app.io.hdf5 import CHANNELS, Recording, RecordingError, merge_skew, validate
from dsp.calibration import ReferenceChain
from dsp.multisine import Plan
from dsp.uncertainty import Budget
from hardware.interfaces import is_dut_channel

SKEW_LINE = re.compile(r"^#\s*skew_s\s*=\s*(\S+)\s*$")
# a several-DUT CSV's skew of one channel: "# skew_s[dut.B] = 6e-06"
CHANNEL_SKEW_LINE = re.compile(r"^#\s*skew_s\[([^\]]*)\]\s*=\s*(\S+)\s*$")
WIDTHS = (2, 3)  # a single-DUT CSV's columns: reference, DUT[, drive]
HEADER_BYTES = 1 << 16  # a several-DUT CSV's comments and header line are within this
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


def _parse_csv(
    handle: BinaryIO, name: str, widths: tuple[int, ...] = WIDTHS, max_rows: int | None = None
) -> tuple[list[np.ndarray], float | None]:
    """The columns (float64 V) of the CSV open in `handle` (binary) and the skew (s) of a
    '# skew_s = ...' comment line, None without one. `widths`: the column counts allowed;
    `max_rows`: more data lines than this are refused before any column is allocated."""
    number = 0  # lines consumed
    skew_s = None
    while True:  # leading comment lines, then one optional header line
        offset = handle.tell()
        raw = handle.readline()
        if not raw:
            break
        if _other_breaks(raw):  # lines end with \r alone (or worse): the text whole
            handle.seek(0)
            return _parse_text(handle.read().decode("utf-8").splitlines(), name, widths)
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
    if max_rows is not None and capacity > max_rows:
        raise RecordingError(
            f"{name}: {capacity} lines of {widths[0]} columns: more samples than a recording "
            f"may hold ({max_rows} rows of {widths[0]} columns)"
        )
    fast = _arrow_columns(handle, capacity, widths)
    if fast is not None:
        return fast, skew_s
    columns: list[np.ndarray] = []
    width: int | None = None
    rows = 0
    while block := handle.read(CSV_BLOCK_BYTES):
        if not block.endswith(b"\n"):
            block += handle.readline()
        data = _fast_block(block, width, widths)
        lines = block.count(b"\n") + (not block.endswith(b"\n"))
        if data is None:
            text_lines = block.decode("utf-8").splitlines()
            data = _parse_lines(text_lines, number, width, name, widths)
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


def _arrow_columns(
    handle: BinaryIO, capacity: int, widths: tuple[int, ...] = WIDTHS
) -> list[np.ndarray] | None:
    """The data rows from the handle's position as float64 columns (V), converted by pyarrow's
    C reader into columns of `capacity` samples allocated once; None (the handle back at its
    position) when the reader refuses anything: a cell that is not a number in its syntax (an
    empty item, a word, a quote, a line break other than \n, \r\n or \r, a non-ASCII
    digit), a row of another width, not `widths` columns, more rows than `capacity` or than a
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
                column_types={f"f{i}": pa.float64() for i in range(max(widths))},
                null_values=[],
                strings_can_be_null=False,
            ),
        )
        width = len(reader.schema)
        if width not in widths:
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


def _parse_text(
    lines: list[str], name: str, widths: tuple[int, ...] = WIDTHS
) -> tuple[list[np.ndarray], float | None]:
    """_parse_csv for text split into lines up front (line breaks other than \\n, \\r\\n)."""
    start = 0
    skew_s = None
    while start < len(lines) and lines[start].lstrip().startswith("#"):
        skew_s = _skew_line(lines[start], start + 1, name, skew_s)
        start += 1
    if start < len(lines) and not _is_numeric_row(lines[start]):
        start += 1  # one header line allowed
    data = _parse_lines(lines[start:], start, None, name, widths)
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


def _fast_block(
    block: bytes, width: int | None, widths: tuple[int, ...] = WIDTHS
) -> np.ndarray | None:
    """A block of whole lines as (rows, columns) float64 by numpy's C reader; None when it
    holds anything but well-formed rows of `widths` numbers (`width` when known), a byte that
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
    if data.shape[1] not in widths or (width is not None and data.shape[1] != width):
        return None
    return data


def _parse_lines(
    lines: list[str],
    before: int,
    width: int | None,
    name: str,
    widths: tuple[int, ...] = WIDTHS,
) -> np.ndarray:
    """Rows of `lines` (the first is line `before` + 1) as (rows, columns) float64, blank lines
    skipped; RecordingError naming the line of a wrong column count or a non-number."""
    rows: list[list[float]] = []
    for number, raw in enumerate(lines, start=before + 1):
        if not raw.strip():
            continue
        cells = [c.strip() for c in raw.replace(";", ",").split(",")]
        if width is None:
            width = len(cells)
            if width not in widths and widths == WIDTHS:
                raise RecordingError(
                    f"{name}: line {number}: {width} columns; expected 2 (reference, DUT) "
                    "or 3 (reference, DUT, drive) in volts"
                )
            if width not in widths:
                raise RecordingError(
                    f"{name}: line {number}: {width} columns where the header names {widths[0]}"
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


def read_csv_channels(
    path: str | Path,
    plan: Plan,
    chain: ReferenceChain,
    budget: Budget,
    *,
    settle_periods: int = 0,
    range_v: float | None = None,
) -> dict[str, Recording]:
    """Read a several-DUT CSV (issue 36): a header line names its columns, in any order:
    "reference", DUT channels `dut.<position>` (`dut.<position>.<axis>`), optionally "drive";
    per DUT channel its two-channel Recording (app.io.channels.member_recordings), in the
    header's order. `# skew_s[dut.B] = 6e-06` gives a channel's skew (s), `# skew_s = ...`
    every other DUT channel's. RecordingError naming the file and the line, column or channel."""
    path = Path(path)
    name = path.name
    try:
        check_input_file(path, MAX_CSV_BYTES, "CSV recording")
    except InputFileError as exc:
        raise RecordingError(str(exc)) from None
    try:
        with open(path, "rb") as handle:
            names, skews = _header(handle.read(HEADER_BYTES), name)
            handle.seek(0)
            width = len(names)
            columns, common_skew_s = _parse_csv(handle, name, (width,), MAX_IMPORT_SAMPLES // width)
    except UnicodeDecodeError as exc:
        raise RecordingError(f"{name}: cannot be read as text ({exc})") from None
    except OSError as exc:
        raise RecordingError(f"{name}: cannot be read as text ({exc})") from None
    by_name = dict(zip(names, columns, strict=True))
    label = {c: f"column {i} {c}" for i, c in enumerate(names, start=1)}
    duts = {
        c: ImportedChannel(by_name[c], skews.get(c, common_skew_s), label[c])
        for c in names
        if is_dut_channel(c)
    }
    return member_recordings(
        name,
        plan,
        chain,
        budget,
        reference_v=by_name["reference"],
        duts=duts,
        drive_v=by_name.get("drive"),
        labels={"reference": label["reference"], "drive": label.get("drive", "drive")},
        settle_periods=settle_periods,
        range_v=range_v,
        source=str(path),
        skew_where="the file's 'skew_s[{channel}] = {{:g}}' line",
    )


def several_dut_columns(path: str | Path) -> tuple[str, ...]:
    """The DUT columns of a several-DUT CSV: those its header names `dut.<position>` (or
    `dut.<position>.<axis>`); () for a file without such a header, which `read_csv` reads as
    today (how `analyze` tells the two apart). Reads at most HEADER_BYTES; RecordingError when
    the file cannot be read or its header is malformed."""
    path = Path(path)
    try:
        check_input_file(path, MAX_CSV_BYTES, "CSV recording")
        with open(path, "rb") as handle:
            head = handle.read(HEADER_BYTES)
    except InputFileError as exc:
        raise RecordingError(str(exc)) from None
    except OSError as exc:
        raise RecordingError(f"{path.name}: cannot be read as text ({exc})") from None
    for line in head.decode("utf-8", errors="replace").splitlines():
        if line.lstrip().startswith("#"):
            continue
        cells = [c.strip() for c in line.replace(";", ",").split(",")]
        if not any(c.startswith("dut.") for c in cells):
            return ()
        names, _ = _header(head, path.name)
        return tuple(c for c in names if is_dut_channel(c))
    return ()


def _header(head: bytes, name: str) -> tuple[list[str], dict[str, float]]:
    """A several-DUT CSV's column names (its first line after the comments) and the skews its
    `# skew_s[channel] = ...` lines give (s); RecordingError naming the line."""
    lines = head.decode("utf-8", errors="replace").splitlines()
    skews: dict[str, float] = {}
    for number, line in enumerate(lines, start=1):
        if line.lstrip().startswith("#"):
            match = CHANNEL_SKEW_LINE.match(line.strip())
            if match:
                skews[match.group(1).strip()] = _skew_value(match.group(2), number, name)
            continue
        if _is_numeric_row(line):
            raise RecordingError(
                f"{name}: line {number}: a CSV of several DUT channels needs a header line "
                "naming its columns (reference, dut.<position>, ..., drive)"
            )
        names = [c.strip() for c in line.replace(";", ",").split(",")]
        check_names(names, f"{name}: line {number}", "column")
        for channel in skews:
            if channel not in names or channel in ("reference", "drive"):
                raise RecordingError(
                    f"{name}: skew_s[{channel}]: no DUT column {channel!r} in the header"
                )
        return names, skews
    raise RecordingError(
        f"{name}: no header line naming the columns in its first {HEADER_BYTES} bytes"
    )


def _skew_value(text: str, number: int, name: str) -> float:
    """A skew line's value (s), finite within +-1 s; RecordingError naming the line."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and abs(value) <= 1.0):
        raise RecordingError(
            f"{name}: line {number}: skew_s {text!r} is not a delay in s (finite, within +-1 s)"
        )
    return value
