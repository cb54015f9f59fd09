"""Outputs (issues "Hardening" and "Safety"): every file is written whole or not at all (temp
file, fsync, rename; a full disk, a read-only folder or Ctrl-C leaves nothing), with the usual
mode; what sits at an output path is never destroyed: only a regular file (or nothing) is
replaced, keeping its mode and any link to it; devices and FIFOs are written as streams;
anything else is refused by name and left as it was."""

import errno
import os
import socket
import stat
import subprocess
import threading
from pathlib import Path

import pytest
from click.testing import CliRunner
from PIL import Image

from im2vec_cli.cli import cli
from im2vec_cli.files import atomic_write
from tests.cli.bad_input import EXE
from tests.helpers import check_svg, png


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


# --- whole files or none (issue "Hardening") ---------------------------------------------------


def test_read_only_output_folder(tmp_path, model_dir, monkeypatch):
    src = png(tmp_path / "a.png")
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    if os.geteuid() == 0:  # root ignores permissions: make creating the temp file fail as it would
        real_open = os.open

        def denied(path, *a, **k):
            if Path(path).parent == ro:
                raise PermissionError(errno.EACCES, "Permission denied", str(path))
            return real_open(path, *a, **k)

        monkeypatch.setattr(os, "open", denied)
    res = CliRunner().invoke(cli, ["vectorize", src, "-o", str(ro / "out.svg"), "--model", model_dir])
    ro.chmod(0o755)
    assert res.exit_code == 1 and res.stderr.startswith("Error:") and len(res.stderr.splitlines()) == 1
    assert list(ro.iterdir()) == []


def test_disk_full_leaves_nothing(tmp_path, model_dir, monkeypatch):
    """A write that fails half-way (ENOSPC at fsync) leaves neither the target nor a temp file."""
    src = png(tmp_path / "a.png")
    out = tmp_path / "o"
    out.mkdir()

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    res = CliRunner().invoke(cli, ["vectorize", src, "-o", str(out / "a.svg"), "--model", model_dir])
    assert res.exit_code == 1 and "No space left" in res.stderr and len(res.stderr.splitlines()) == 1
    assert list(out.iterdir()) == []


def test_real_processes_stdin_closed_and_stdout_full(tmp_path, model_dir):
    """Real subprocesses: stdin closed, stdout on a full device, an unknown option."""
    src = png(tmp_path / "a.png", 32, 32)
    cmd = " ".join(EXE) + f" vectorize - --model {model_dir}"
    r = subprocess.run(["bash", "-c", f"exec 0<&-; {cmd}"], capture_output=True, text=True)
    assert r.returncode == 1 and r.stderr.startswith("Error: stdin") and r.stderr.count("\n") == 1, r.stderr
    if os.path.exists("/dev/full"):
        r = subprocess.run(["bash", "-c", f"{cmd} < {src} > /dev/full"], capture_output=True, text=True)
        assert r.returncode == 1 and "No space left" in r.stderr and r.stderr.count("\n") == 1, r.stderr
    r = subprocess.run(EXE + ["vectorize", src, "--nope"], capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr and "No such option" in r.stderr


def test_an_interrupt_just_after_the_temp_file_is_made_leaves_nothing(tmp_path, monkeypatch):
    """Ctrl-C can land between the temporary file's creation and the code that would remove it
    (a batch interrupted mid-write left `.g011.svg.XXXX.tmp` behind): it is removed all the same."""
    from im2vec_cli.files import atomic_write

    real_open = os.open

    def created_then_interrupted(path, *a, **k):
        real_open(path, *a, **k)
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "open", created_then_interrupted)
    with pytest.raises(KeyboardInterrupt):
        atomic_write(tmp_path / "a.svg", "<svg/>", durable=False)
    monkeypatch.undo()
    assert list(tmp_path.iterdir()) == []


def test_outputs_get_the_usual_file_mode(tmp_path):
    """Atomic writes go through a temporary file; the final file follows the umask."""
    from im2vec_cli.files import atomic_write

    old = os.umask(0o022)
    try:
        atomic_write(tmp_path / "a.svg", "<svg/>")
    finally:
        os.umask(old)
    assert (tmp_path / "a.svg").stat().st_mode & 0o777 == 0o644


def test_clashing_names_keep_their_extensions(tmp_path, model_dir):
    d = tmp_path / "in"
    d.mkdir()
    for name in ("x.png", "x.jpg", "x.PNG", "y.png"):
        Image.open(png(tmp_path / "src.png")).convert("RGB").save(d / name, format="JPEG" if name.endswith("jpg") else "PNG")
    res = CliRunner().invoke(cli, ["vectorize", str(d), "-o", str(tmp_path / "out"), "--model", model_dir])
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["x.PNG.svg", "x.jpg.svg", "x.png.svg", "y.svg"]
    assert sum(line.startswith("Warning:") for line in res.stderr.splitlines()) == 1 and "x.jpg" in res.stderr


def test_longest_legal_name_is_writable(tmp_path, model_dir):
    name = "g" * 251 + ".svg"  # 255 bytes: the longest name this file system takes
    res = CliRunner().invoke(cli, ["vectorize", png(tmp_path / "a.png"), "-o", str(tmp_path / name), "--no-refine",
                                   "--model", model_dir])
    assert res.exit_code == 0, res.output
    check_svg((tmp_path / name).read_text(), 40, 24)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
