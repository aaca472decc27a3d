import errno
import os

import pytest

from deckpose.atomic_io import atomic_open, atomic_path, write_bytes


def test_atomic_open_writes_whole_file_with_normal_mode(tmp_path):
    p = tmp_path / "a.txt"
    with atomic_open(p) as fh:
        fh.write("hello")
        assert not p.exists()  # nothing visible until the block ends
    assert p.read_text() == "hello"
    umask = os.umask(0)
    os.umask(umask)
    assert (p.stat().st_mode & 0o777) == 0o666 & ~umask


def test_failure_leaves_old_file_and_no_temporaries(tmp_path):
    p = tmp_path / "b.txt"
    p.write_text("old")
    with pytest.raises(RuntimeError), atomic_path(p) as tmp:
        tmp.write_text("half")
        raise RuntimeError("crash")
    assert p.read_text() == "old"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["b.txt"]


def test_write_bytes_names_the_file_when_the_disk_is_full(tmp_path, monkeypatch):
    """A failed fsync (a full disk) names no file; write_bytes names it, and leaves the old file whole."""
    p = tmp_path / "frame.png"
    p.write_bytes(b"old")

    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "fsync", full)
    with pytest.raises(OSError, match="frame.png") as info:
        write_bytes(p, b"new bytes")
    assert info.value.errno == errno.ENOSPC
    assert p.read_bytes() == b"old"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["frame.png"]
