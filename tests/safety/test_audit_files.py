"""The small-file reader where the file system does not behave: short reads, sizes of 0,
failing reads, and a path swapped between the look and the open (SR-AUD-1, SR-EVD-1).

A regular file normally comes back whole from one read; ``/proc`` files report a size of 0,
pipes and network file systems return short reads, and a path can change between ``stat`` and
``open``. The operating system is replaced here, for the reader's module only, by one that does
each of those things, so the loop and the second check that guard against them are exercised.
"""

from __future__ import annotations

import errno
import fcntl
import os
from pathlib import Path

import pytest

from safety.audit.files import FileReadError, open_regular, read_small_file

CODE = ["safety/audit/files.py"]


class _ShortReads:
    """``os.read`` that returns at most ``chunk`` bytes and records what was asked for."""

    def __init__(self, chunk: int) -> None:
        self.chunk = chunk
        self.asked: list[int] = []
        self.real = os.read

    def __call__(self, fd: int, n: int) -> bytes:
        self.asked.append(n)
        return self.real(fd, min(n, self.chunk))


def _sizeless(monkeypatch: pytest.MonkeyPatch) -> None:
    """``os.fstat`` that reports a size of 0 for every file, as ``/proc`` files do."""
    real = os.fstat

    def fstat(fd: int) -> os.stat_result:
        st = real(fd)
        fields = list(st)
        fields[6] = 0  # st_size
        return os.stat_result(fields)

    monkeypatch.setattr(os, "fstat", fstat)


@pytest.mark.requirement("SR-EVD-1", kind="example", code=CODE)
def test_short_reads_are_joined_and_never_read_past_the_limit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "f"
    path.write_bytes(b"abcdefgh")
    _sizeless(monkeypatch)
    reads = _ShortReads(3)
    monkeypatch.setattr(os, "read", reads)
    assert read_small_file(path, 8) == b"abcdefgh"
    assert reads.asked == [9, 6, 3, 1]  # never more than limit + 1 in all
    # Exactly at the limit after a read: one more read shows whether there is more.
    path.write_bytes(b"abcdefghijkl")
    reads.asked.clear()
    reads.chunk = 4
    with pytest.raises(FileReadError) as caught:
        read_small_file(path, 8)
    assert str(caught.value) == f"{path}: more than 8 bytes; at most 8 bytes expected"
    assert reads.asked == [9, 5, 1]
    assert sum(min(n, 4) for n in reads.asked) <= 9


@pytest.mark.requirement("SR-EVD-1", kind="example", code=CODE)
def test_a_read_the_system_refuses_is_an_io_error_naming_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "f"
    path.write_bytes(b"abc")

    def broken(fd: int, n: int) -> bytes:
        raise OSError(errno.EIO, os.strerror(errno.EIO))

    monkeypatch.setattr(os, "read", broken)
    with pytest.raises(FileReadError) as caught:
        read_small_file(path, 8)
    error = caught.value
    assert str(error) == f"{path}: cannot read (Input/output error)"
    assert (error.path, error.reason) == (path, "cannot read (Input/output error)")
    assert (error.io_error, error.missing) == (True, False)


@pytest.mark.requirement("SR-EVD-1", kind="example", code=CODE)
def test_a_path_swapped_between_the_look_and_the_open_is_caught(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``stat`` sees a regular file; by the open it is gone, a link or a FIFO."""
    regular = tmp_path / "regular"
    regular.write_bytes(b"x")
    seen = os.stat(regular)
    monkeypatch.setattr(os, "stat", lambda *a, **k: seen)
    with pytest.raises(FileReadError) as caught:
        open_regular(tmp_path / "gone")
    assert str(caught.value) == f"{tmp_path / 'gone'}: no such file"
    assert (caught.value.path, caught.value.reason) == (tmp_path / "gone", "no such file")
    assert (caught.value.missing, caught.value.io_error) == (True, False)
    link = tmp_path / "link"
    link.symlink_to(regular)
    with pytest.raises(FileReadError) as caught:
        open_regular(link, follow_symlinks=False)
    assert str(caught.value) == f"{link}: not a regular file (a symbolic link)"
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    # A reader and a writer hold it open, so even an open that blocks returns at once.
    ends = [os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)]
    ends.append(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
    try:
        before = len(os.listdir("/proc/self/fd"))
        with pytest.raises(FileReadError) as caught:
            open_regular(fifo)  # refused on the descriptor, which is closed again
        assert len(os.listdir("/proc/self/fd")) == before
        assert str(caught.value) == f"{fifo}: not a regular file (a FIFO)"
        assert (caught.value.path, caught.value.reason) == (fifo, "not a regular file (a FIFO)")
    finally:
        for end in ends:
            os.close(end)


@pytest.mark.requirement("SR-EVD-1", kind="example", code=CODE)
def test_the_descriptor_is_read_only_non_blocking_not_inherited_and_links_are_followed(
    tmp_path: Path,
) -> None:
    target = tmp_path / "target"
    target.write_bytes(b"x")
    link = tmp_path / "link"
    link.symlink_to(target)
    fd = open_regular(link)
    try:
        flags = fcntl.fcntl(fd, fcntl.F_GETFL)
        assert flags & os.O_ACCMODE == os.O_RDONLY
        assert flags & os.O_NONBLOCK
        assert not os.get_inheritable(fd)
    finally:
        os.close(fd)


@pytest.mark.requirement("SR-EVD-1", kind="example", code=CODE)
def test_an_open_the_system_refuses_is_an_io_error_even_for_a_loop_of_links(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Links followed, a loop the system reports is not "a symbolic link" but a refused open."""
    path = tmp_path / "f"
    path.write_bytes(b"x")
    for code, text in ((errno.EACCES, "Permission denied"), (errno.ELOOP, "Too many levels")):

        def refuse(*args: object, code: int = code, **kwargs: object) -> int:
            raise OSError(code, os.strerror(code))

        monkeypatch.setattr(os, "open", refuse)
        with pytest.raises(FileReadError) as caught:
            open_regular(path)
        assert str(caught.value).startswith(f"{path}: cannot open ({text}")
        assert caught.value.reason == f"cannot open ({os.strerror(code)})"
        assert (caught.value.path, caught.value.io_error, caught.value.missing) == (
            path,
            True,
            False,
        )
        monkeypatch.undo()
