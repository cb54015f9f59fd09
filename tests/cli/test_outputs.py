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


def test_a_trailing_slash_names_a_folder(tmp_path, model_dir):
    """``-o NAME/``: a folder. Onto an existing file it is refused and the file kept (it was
    replaced, exit 0); a new name becomes a folder with the SVG in it (it was a file NAME)."""
    src = png(tmp_path / "a.png")
    existing = tmp_path / "existing.svg"
    existing.write_text("someone's work")
    res = CliRunner().invoke(cli, ["vectorize", src, "-o", f"{existing}/", "--model", model_dir])
    assert res.exit_code == 1 and res.stderr.splitlines() == [
        f"Error: {existing}/: ends with a slash, which names a folder, but {existing} is not a folder"]
    assert existing.read_text() == "someone's work"
    res = CliRunner().invoke(cli, ["vectorize", src, "-o", f"{tmp_path / 'newdir'}/", "--model", model_dir])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "newdir").is_dir()
    check_svg((tmp_path / "newdir" / "a.svg").read_text(), 40, 24)
    res = CliRunner().invoke(cli, ["render", str(tmp_path / "newdir" / "a.svg"), "-o", f"{tmp_path / 'x.png'}/"])
    assert res.exit_code == 1 and "ends with a slash, which names a folder; give a file name" in res.stderr
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("case", ["read-only", "onto a file", "through a file"])
def test_an_output_folder_that_cannot_be_written_is_one_line_before_any_work(tmp_path, model_dir, monkeypatch, case):
    """Five pictures into a folder that cannot take them: one error line (it was the same line
    five times, once per picture), exit 1, nothing written anywhere."""
    srcs = [png(tmp_path / f"p{i}.png") for i in range(5)]
    blocker = tmp_path / "file"
    blocker.write_text("x")
    out = {"read-only": tmp_path / "ro", "onto a file": blocker, "through a file": blocker / "sub"}[case]
    if case == "read-only":
        out.mkdir()
        out.chmod(0o555)
        real_open = os.open

        def denied(path, *a, **k):  # root ignores permissions: fail as a read-only folder would
            if Path(path) == out or Path(path).parent == out:
                raise PermissionError(errno.EACCES, "Permission denied", str(path))
            return real_open(path, *a, **k)

        monkeypatch.setattr(os, "open", denied)
    res = CliRunner().invoke(cli, ["vectorize", *srcs, "-o", str(out), "--model", model_dir])
    monkeypatch.undo()
    if case == "read-only":
        out.chmod(0o755)
        assert list(out.iterdir()) == []
    assert res.exit_code == 1 and len(res.stderr.splitlines()) == 1 and res.stderr.startswith(f"Error: {out}")
    assert blocker.read_text() == "x"


def test_a_file_given_twice_is_vectorized_once_and_said(tmp_path, model_dir):
    src = png(tmp_path / "a.png")
    other = png(tmp_path / "b.png", 30, 30)
    res = CliRunner().invoke(cli, ["vectorize", src, other, src, str(tmp_path / "." / "a.png"), "-o",
                                   str(tmp_path / "out"), "--model", model_dir])
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["a.svg", "b.svg"]
    assert res.stderr.count("is given twice") == 2 and "two inputs would be written" not in res.stderr
