"""Writing files so that no reader ever sees a torn file and nothing stored is overwritten.

Every write goes to a temporary name in the target's own folder, is flushed to disk, and is
then moved into place in one step: `os.link` when the target must not exist yet (the link
fails if it does, so two writers can never both win), `os.replace` when overwriting was asked
for explicitly.
"""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

from app.errors import Refusal

DATA_DIR_ENV = "ACCELCAL_DATA_DIR"


def data_dir() -> Path:
    """The folder of the user's data (the default SQLite records file, the stored stand
    responses): $ACCELCAL_DATA_DIR when set (a demo or a test keeps its own), else the user's
    data directory (platformdirs)."""
    chosen = os.environ.get(DATA_DIR_ENV)
    if chosen:
        return Path(chosen).expanduser()
    from platformdirs import user_data_dir

    return Path(user_data_dir("accelcal", appauthor=False))


# a write the disk refused: no space, the file-size limit, the user's quota
DISK_FULL_ERRNOS = frozenset({errno.ENOSPC, errno.EFBIG, errno.EDQUOT})


def is_disk_full(exc: BaseException) -> bool:
    """Whether `exc` (or what caused it) is a write the disk refused: ENOSPC, EFBIG, EDQUOT
    from the OS, quoted by HDF5 ("errno = 28"), or SQLite's "database or disk is full"."""
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        seen.add(id(current))
        if isinstance(current, OSError) and current.errno in DISK_FULL_ERRNOS:
            return True
        text = str(current)
        if "database or disk is full" in text or any(
            f"errno = {code}," in text for code in DISK_FULL_ERRNOS
        ):
            return True
        current = current.__cause__ or current.__context__
    return False


def disk_full_reason(exc: BaseException) -> str:
    """The path and reason of a refused write, e.g. '/runs/x/.certificate.pdf.tmp: File too
    large' (the path when the error names one)."""
    current: BaseException | None = exc
    while current is not None:
        if isinstance(current, OSError) and current.errno in DISK_FULL_ERRNOS:
            where = f"{current.filename}: " if current.filename else ""
            return f"{where}{current.strerror or os.strerror(current.errno or 0)}"
        current = current.__cause__ or current.__context__
    return str(exc)


class FileExistsRefusal(FileExistsError, Refusal):
    """The target exists and overwriting was not asked for."""


class TargetRefusal(Refusal):
    """A target that must not be written: an input of the same command, or a folder."""


def _same(a: Path, b: Path) -> bool:
    if a.exists() and b.exists():
        return os.path.samefile(a, b)  # any name of the same file (links included)
    return a.resolve() == b.resolve()


def check_target(
    target: str | Path, *, inputs: tuple[str | Path | None, ...] = (), overwrite: bool = False
) -> None:
    """Refuse, before anything is done, to write `target` when it is one of `inputs` (under any
    name; even with `overwrite`), a folder, or an existing file without `overwrite`."""
    target = Path(target)
    for source in inputs:
        if source is not None and _same(target, Path(source)):
            raise TargetRefusal(f"{target}: is an input of this command; it is never overwritten")
    if target.is_dir():
        raise TargetRefusal(f"{target}: is a folder; name a file")
    if target.exists() and not overwrite:
        raise FileExistsRefusal(f"{target}: exists; it is never overwritten")


def _fsync_dir(folder: Path) -> None:
    """Flush a folder's entry table (a rename is durable only then); best effort."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextlib.contextmanager
def staged(target: str | Path, *, overwrite: bool = False) -> Iterator[Path]:
    """A temporary path beside `target` to write to; on leaving the block without an error it
    becomes `target` in one step. FileExistsRefusal when `target` exists and not `overwrite`
    (checked before and, atomically, at the end); the temporary file never outlives the block.
    """
    target = Path(target)
    folder = target.parent if str(target.parent) else Path(".")
    if not overwrite and target.exists():
        raise FileExistsRefusal(f"{target}: exists; it is never overwritten")
    fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=folder)
    os.close(fd)
    temporary = Path(name)
    try:
        yield temporary
        with temporary.open("rb+") as handle:
            os.fsync(handle.fileno())
        if overwrite:
            os.replace(temporary, target)
        else:
            try:
                os.link(temporary, target)
            except FileExistsError:
                raise FileExistsRefusal(f"{target}: exists; it is never overwritten") from None
        _fsync_dir(folder)
    finally:
        with contextlib.suppress(FileNotFoundError):
            temporary.unlink()


def write_new(target: str | Path, data: bytes | str, *, overwrite: bool = False) -> Path:
    """Write `data` (str as UTF-8) to `target` atomically; see `staged`."""
    payload = data.encode("utf-8") if isinstance(data, str) else data
    with staged(target, overwrite=overwrite) as temporary:
        temporary.write_bytes(payload)
    return Path(target)


def write_with(
    target: str | Path, writer: Callable[[Path], None], *, overwrite: bool = False
) -> Path:
    """Let `writer(path)` write a file (e.g. a PDF or HDF5 library) at a temporary path, then
    move it into place atomically; see `staged`."""
    with staged(target, overwrite=overwrite) as temporary:
        writer(temporary)
    return Path(target)
