"""Opening the files a user hands the station: regular files only, of a bounded size.

Every file the station reads on a user's word (station config, survey YAML, observation files,
times files, captures, a session's raw log) goes through here, so that ``/dev/zero``, a FIFO, a
folder, an unreadable path or a 4 GB file given by mistake is one line naming the file, not a
hang, a machine out of memory or a traceback. The file is opened with ``O_NONBLOCK`` (opening a
FIFO with no writer would otherwise block forever), then ``fstat`` says what it is, and at most
``max_bytes + 1`` bytes are read, so a file that grows or lies about its size (``/proc``) is
still bounded.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import os
import stat
import tempfile
from collections.abc import Iterable, Iterator
from typing import BinaryIO

from station.errors import InputError

MiB = 1024 * 1024

#: size limits, far above any real file of the kind and far below what would hurt the laptop
MAX_YAML = 4 * MiB  # a station config or survey: a few kB
MAX_TIMES = 4 * MiB  # a hand-typed times file: under a kB
MAX_OBSERVATIONS = 64 * MiB  # a total-station observation file: tens of kB
MAX_CAPTURE = 2048 * MiB  # a plain capture or a day's raw log: a few MB a day
MAX_RAWLOG = 2048 * MiB


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a pipe (FIFO)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def _size(n: int) -> str:
    return f"{n / MiB:.1f} MB" if n >= MiB else f"{n} bytes"


def _open_error(exc: OSError, path: str, what: str) -> InputError:
    if exc.errno == errno.ENOENT:
        reason = "no such file"
    elif exc.errno == errno.EACCES:
        reason = "permission denied"
    elif exc.errno == errno.EISDIR:
        reason = "it is a folder"
    else:
        reason = exc.strerror or str(exc)
    return InputError(f"cannot read {what}: {reason}", path=path)


def check_regular(path: str, max_bytes: int, what: str = "file") -> os.stat_result:
    """Raise :class:`InputError` unless ``path`` names a readable regular file of at most
    ``max_bytes``; without opening it (for a file that is copied or opened later)."""
    if not path:
        raise InputError(f"empty path for the {what}")
    try:
        st = os.stat(path)
    except (OSError, ValueError) as exc:
        if isinstance(exc, ValueError):
            raise InputError(f"not a valid path for the {what}", path=repr(path)) from None
        raise _open_error(exc, path, what) from None
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"is {_kind(st.st_mode)}, not a {what}", path=path)
    if st.st_size > max_bytes:
        raise InputError(
            f"is {_size(st.st_size)}; a {what} is at most {_size(max_bytes)}", path=path
        )
    if not os.access(path, os.R_OK):
        raise InputError(f"cannot read {what}: permission denied", path=path)
    return st


def open_regular(path: str, max_bytes: int, what: str = "file") -> BinaryIO:
    """Open ``path`` for reading in binary, refusing anything but a regular file of at most
    ``max_bytes``. The caller must still read at most ``max_bytes + 1`` bytes (see
    :func:`read_bytes`) if the file may grow while it is read."""
    if not path:
        raise InputError(f"empty path for the {what}")
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except ValueError:
        raise InputError(f"not a valid path for the {what}", path=repr(path)) from None
    except OSError as exc:
        raise _open_error(exc, path, what) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"is {_kind(st.st_mode)}, not a {what}", path=path)
        if st.st_size > max_bytes:
            raise InputError(
                f"is {_size(st.st_size)}; a {what} is at most {_size(max_bytes)}", path=path
            )
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_bytes(path: str, max_bytes: int, what: str = "file") -> bytes:
    """The whole file, refusing special files and files over ``max_bytes``."""
    with open_regular(path, max_bytes, what) as fh:
        try:
            data = fh.read(max_bytes + 1)
        except OSError as exc:
            raise _open_error(exc, path, what) from None
    if len(data) > max_bytes:
        raise InputError(f"is larger than {_size(max_bytes)}, the limit for a {what}", path=path)
    return data


def decode_text(data: bytes, path: str, what: str = "file", encoding: str = "utf-8") -> str:
    """Bytes as text; a byte that is not ``encoding`` is one line naming its line number."""
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        bad = data[exc.start : exc.start + 1].hex()
        raise InputError(
            f"not a UTF-8 text {what} (byte 0x{bad}); save it as UTF-8", path=path, line=line
        ) from None


def read_text(path: str, max_bytes: int, what: str = "file", encoding: str = "utf-8") -> str:
    """The whole file as text (a UTF-8 byte-order mark is dropped)."""
    text = decode_text(read_bytes(path, max_bytes, what), path, what, encoding)
    return text[1:] if text.startswith("\ufeff") else text


def check_output(arg: str, option: str) -> str:
    """Check an output file before any work is done, so a day is not replayed and fitted only
    to fail at the last step with a traceback: its folder must exist and be writable, and the
    path must not be a folder or a special file (``/dev/null`` is fine). ``option`` is what
    named the file (``--csv``, ``results.csv``), for the message."""
    folder = os.path.dirname(os.path.abspath(arg))
    if os.path.isdir(arg):
        raise InputError("is a folder; give a file name (or - for standard output)",
                         path=arg, field=option)  # fmt: skip
    if not os.path.exists(folder):
        raise InputError(f"folder {folder} does not exist", path=arg, field=option)
    if not os.path.isdir(folder):
        raise InputError(f"{folder} is not a folder", path=arg, field=option)
    if os.path.exists(arg):
        mode = os.stat(arg).st_mode
        if not stat.S_ISREG(mode) and os.path.abspath(arg) != os.devnull:
            raise InputError("is not a regular file", path=arg, field=option)
        if not os.access(arg, os.W_OK):
            raise InputError("file is not writable", path=arg, field=option)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"folder {folder} is not writable", path=arg, field=option)
    try:  # the permission bits are not the whole story (root, read-only mounts, /sys)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError as exc:
        raise InputError(f"folder {folder} is not writable ({exc.strerror})",
                         path=arg, field=option) from None  # fmt: skip
    return arg


def _temp_beside(path: str) -> str:
    """An empty temporary file in the folder of ``path`` (same file system: the rename is
    atomic), its name beginning with a dot, made with the mode ``open()`` gives a new file
    (the umask applied by the system: no mkstemp 0600 to change, no umask to read)."""
    folder, name = os.path.split(os.path.abspath(path))
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)
    for _ in range(100):
        tmp = os.path.join(folder, f".{name}-{os.urandom(6).hex()}")
        try:
            os.close(os.open(tmp, flags, 0o666))
        except FileExistsError:
            continue
        return tmp
    raise FileExistsError(errno.EEXIST, "no free temporary name", folder)


@contextlib.contextmanager
def _renamed(tmp: str, path: str | None) -> Iterator[str]:
    """Rename ``tmp`` over ``path`` (None: remove it) when the block ends; remove it when the
    block raises."""
    try:
        yield tmp
        if path is None:
            os.unlink(tmp)
            return
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


@contextlib.contextmanager
def replaced(path: str) -> Iterator[str]:
    """The one atomic write of the station: a temporary file beside ``path`` for the block to
    write, renamed over ``path`` when it ends, so a reader sees the old file or the new one,
    never half of one; a block that raises leaves ``path`` as it was."""
    with _renamed(_temp_beside(path), path) as tmp:
        yield tmp


def write_atomic(path: str, pieces: Iterable[bytes | memoryview]) -> str:
    """Write ``pieces`` as the file ``path`` (:func:`replaced`), without joining them (a
    2000-descent results CSV is 0.6 MB); returns the SHA-256 of what was written."""
    digest = hashlib.sha256()
    with replaced(path) as tmp, open(tmp, "wb") as fh:
        for piece in pieces:
            fh.write(piece)
            digest.update(piece)
    return digest.hexdigest()


@contextlib.contextmanager
def staged_output(arg: str, option: str) -> Iterator[str]:
    """A temporary file beside the output, renamed over it only when the writing succeeded
    (:func:`replaced`), so a failed command leaves the previous file intact and never half a
    file."""
    check_output(arg, option)
    try:
        tmp = _temp_beside(arg)
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror}", path=arg, field=option) from None
    with _renamed(tmp, None if os.path.abspath(arg) == os.devnull else arg):
        yield tmp
