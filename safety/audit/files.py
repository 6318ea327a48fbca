"""Bounded reads of small trusted-format files: keys, anchors, manifests (SR-AUD-1, SR-EVD-1).

A key, a head anchor or a manifest is a small regular file. Whoever supplies the path may hand
over a FIFO (a read that never returns), a device (``/dev/zero``: a read that never ends), a
directory, or a file of gigabytes. :func:`read_small_file` checks the kind of file *before*
opening it (opening some devices has effects: a serial port toggles its control lines), opens
it without blocking, checks the kind again on the open descriptor (the path may have been
swapped in between) and reads at most ``limit`` bytes.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from pipeline.errors import SafecaseError

__all__ = ["FileReadError", "file_kind", "open_regular", "read_small_file"]

_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a FIFO"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISLNK, "a symbolic link"),
)


class FileReadError(SafecaseError, ValueError):
    """A file that cannot be read as asked: missing, unreadable, not a regular file, too large.

    ``str(error)`` is ``"<path>: <reason>"``; ``missing`` is True when nothing is at the path,
    ``io_error`` when the operating system refused (permissions, I/O), not the file's kind or size.
    """

    def __init__(
        self, path: Path | str, reason: str, *, missing: bool = False, io_error: bool = False
    ) -> None:
        super().__init__(f"{path}: {reason}")
        self.path = Path(path)
        self.reason = reason
        self.missing = missing
        self.io_error = io_error


def file_kind(mode: int) -> str:
    """What a ``st_mode`` is, for messages: ``"a regular file"``, ``"a FIFO"``, ..."""
    for test, name in _KINDS:
        if test(mode):
            return name
    return "a regular file" if stat.S_ISREG(mode) else "an unknown kind of file"


def open_regular(
    path: Path | str, *, follow_symlinks: bool = True, dir_fd: int | None = None
) -> int:
    """A read-only descriptor of the regular file at ``path`` (relative to ``dir_fd`` if given).

    Raises :class:`FileReadError` naming the path when nothing is there, when it cannot be
    opened, when it is not a regular file, or (``follow_symlinks`` False) when it is a link.
    The caller closes the descriptor.
    """
    try:
        before = os.stat(path, dir_fd=dir_fd, follow_symlinks=follow_symlinks)
    except FileNotFoundError:
        raise FileReadError(path, "no such file", missing=True) from None
    except OSError as exc:
        raise FileReadError(path, f"cannot open ({exc.strerror})", io_error=True) from None
    if not stat.S_ISREG(before.st_mode):
        raise FileReadError(path, f"not a regular file ({file_kind(before.st_mode)})")
    flags = os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC | (0 if follow_symlinks else os.O_NOFOLLOW)
    try:
        fd = os.open(path, flags, dir_fd=dir_fd)
    except FileNotFoundError:
        raise FileReadError(path, "no such file", missing=True) from None
    except OSError as exc:
        if exc.errno == errno.ELOOP and not follow_symlinks:
            raise FileReadError(path, "not a regular file (a symbolic link)") from None
        raise FileReadError(path, f"cannot open ({exc.strerror})", io_error=True) from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise FileReadError(path, f"not a regular file ({file_kind(mode)})")
    return fd


def read_small_file(
    path: Path | str, limit: int, *, follow_symlinks: bool = True, dir_fd: int | None = None
) -> bytes:
    """The bytes of the regular file at ``path``, at most ``limit`` of them [bytes].

    Raises :class:`FileReadError` as :func:`open_regular` does, and when the file holds more
    than ``limit`` bytes (checked on what is read, not only on the size the file system reports:
    ``/proc`` files report 0).
    """
    fd = open_regular(path, follow_symlinks=follow_symlinks, dir_fd=dir_fd)
    try:
        size = os.fstat(fd).st_size
        if size > limit:
            raise FileReadError(path, f"{size} bytes; at most {limit} bytes expected")
        chunks: list[bytes] = []
        total = 0
        while total <= limit:
            try:
                chunk = os.read(fd, limit + 1 - total)
            except OSError as exc:
                raise FileReadError(path, f"cannot read ({exc.strerror})", io_error=True) from None
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
        if total > limit:
            raise FileReadError(path, f"more than {limit} bytes; at most {limit} bytes expected")
        return b"".join(chunks)
    finally:
        os.close(fd)
