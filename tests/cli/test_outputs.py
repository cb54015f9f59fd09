"""What sits at an output path is never destroyed (issue "Safety", outputs): only a regular
file (or nothing) is replaced, keeping its mode and any link to it; devices and FIFOs are
written as streams; anything else is refused by name and left as it was."""

import os
import socket
import stat
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from im2vec_cli.files import atomic_write
from tests.helpers import make_tiny_model, png

EXE = [sys.executable, "-m", "im2vec_cli"]


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory):
    return make_tiny_model(tmp_path_factory.mktemp("m") / "tiny")


def test_dev_null_is_written_to_not_replaced():
    before = os.stat("/dev/null")
    atomic_write("/dev/null", "<svg/>")
    after = os.stat("/dev/null")
    assert stat.S_ISCHR(after.st_mode) and after.st_rdev == before.st_rdev and after.st_ino == before.st_ino


def test_a_fifo_gets_the_bytes_and_stays_a_fifo(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    atomic_write(fifo, "<svg/>")
    reader.join(10)
    assert got == [b"<svg/>"] and stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_a_link_stays_a_link_and_its_file_gets_the_bytes(tmp_path):
    target = tmp_path / "real.svg"
    target.write_text("old")
    link = tmp_path / "link.svg"
    link.symlink_to(target)
    atomic_write(link, "new")
    assert link.is_symlink() and os.readlink(link) == str(target) and target.read_text() == "new"


def test_a_replaced_file_keeps_its_mode(tmp_path):
    out = tmp_path / "a.svg"
    out.write_text("old")
    out.chmod(0o600)
    atomic_write(out, "new")
    assert out.read_text() == "new" and stat.S_IMODE(out.stat().st_mode) == 0o600


def test_what_is_not_a_file_device_or_fifo_is_refused_and_left(tmp_path):
    folder = tmp_path / "d"
    folder.mkdir()
    broken = tmp_path / "broken.svg"
    broken.symlink_to(tmp_path / "nowhere")
    sock_path = tmp_path / "s"
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(sock_path))
    try:
        for path, word in ((folder, "folder"), (broken, "broken link"), (sock_path, "not a regular file")):
            with pytest.raises(OSError, match=word):
                atomic_write(path, "<svg/>")
        assert folder.is_dir() and broken.is_symlink() and stat.S_ISSOCK(os.lstat(sock_path).st_mode)
        assert sorted(p.name for p in tmp_path.iterdir()) == ["broken.svg", "d", "s"]  # no temp file left
    finally:
        sock.close()


def test_vectorize_to_dev_null_and_dev_stdout(tmp_path, model_dir):
    """`-o /dev/null` discards and exits 0; `-o /dev/full` is one error line; `-o /dev/stdout` (a
    link to /proc/self/fd/1, here a pipe) sends the SVG down the pipe; a socket as output is one
    error line."""
    src = png(tmp_path / "a.png")
    r = subprocess.run(EXE + ["vectorize", src, "-o", "/dev/null", "--model", model_dir], capture_output=True)
    assert r.returncode == 0 and r.stdout == b"" and stat.S_ISCHR(os.stat("/dev/null").st_mode), r.stderr
    if os.path.exists("/dev/full"):  # writes fail with ENOSPC: one line, and the device is still there
        r = subprocess.run(EXE + ["vectorize", src, "-o", "/dev/full", "--model", model_dir], capture_output=True,
                           text=True)
        assert r.returncode == 1 and "No space left" in r.stderr and r.stderr.count("\n") == 1, r.stderr
        assert stat.S_ISCHR(os.stat("/dev/full").st_mode)
    r = subprocess.run(EXE + ["vectorize", src, "-o", "/dev/stdout", "--model", model_dir], capture_output=True)
    assert r.returncode == 0 and r.stdout.startswith(b"<svg") and r.stdout.rstrip().endswith(b"</svg>"), r.stderr
    sock_path = tmp_path / "s"
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(sock_path))
    try:
        r = subprocess.run(EXE + ["vectorize", src, "-o", str(sock_path), "--model", model_dir], capture_output=True,
                           text=True)
        assert r.returncode == 1 and r.stderr.startswith("Error:") and r.stderr.count("\n") == 1, r.stderr
        assert str(sock_path) in r.stderr and "Traceback" not in r.stderr
        assert stat.S_ISSOCK(os.lstat(sock_path).st_mode)
    finally:
        sock.close()
    assert Path("/dev/null").exists()
