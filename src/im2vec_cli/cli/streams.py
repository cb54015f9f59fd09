"""Standard input and output, and files given on the command line (``-`` is stdin/stdout).

Every write to a file is atomic (``files.atomic_write``); every failure is one ``Im2VecError`` line.
"""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

from ..errors import Im2VecError


def read_input(path: str, limit: int | None = None) -> bytes:
    """The bytes of a file, or of stdin for ``-`` (at most ``limit``, default ``files.MAX_INPUT_BYTES``)."""
    from ..files import MAX_INPUT_BYTES, read_capped, read_file

    limit = limit or MAX_INPUT_BYTES
    if path != "-":
        return read_file(path, limit)
    if sys.stdin is None or sys.stdin.closed:
        raise Im2VecError("stdin is closed")
    try:
        return read_capped(sys.stdin.buffer, "stdin", limit)
    except (OSError, ValueError) as exc:
        raise Im2VecError(f"stdin: cannot read ({getattr(exc, 'strerror', None) or exc})") from None


def load_input_image(item: str, max_pixels: int | None = None):
    """An image file (or ``-``: stdin) as ``(H, W, 3)`` float32 in [0, 1] over white (at most
    ``max_pixels``, checked before decoding; ``files.load_picture``: no torch)."""
    from ..files import MAX_PIXELS, load_picture

    most = MAX_PIXELS if max_pixels is None else max_pixels
    if item == "-":
        return load_picture("<stdin>", read_input("-"), most)
    return load_picture(item, max_pixels=most)


def write_stdout(raw: bytes) -> None:
    """Write to stdout; a closed pipe or a full device is one ``Im2VecError`` line, and
    stdout is then pointed at /dev/null so that Python's exit flush stays quiet."""
    try:
        if sys.stdout is None:
            raise OSError("stdout is closed")
        sys.stdout.buffer.write(raw)
        sys.stdout.buffer.flush()
    except (OSError, ValueError) as exc:
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            os.close(devnull)
        except (OSError, ValueError, AttributeError):
            pass
        why = "closed (broken pipe)" if isinstance(exc, BrokenPipeError) else (getattr(exc, "strerror", None) or exc)
        raise Im2VecError(f"stdout: cannot write ({why})") from None


def write_output(path: str | os.PathLike, data: bytes | str, *, parents: bool = False) -> None:
    """Write to stdout for ``-``, else atomically (creating the folders above it with
    ``parents``); a failed write is one ``Im2VecError`` line."""
    from ..files import atomic_write

    raw = data.encode("utf-8") if isinstance(data, str) else data
    if str(path) == "-":
        write_stdout(raw)
        return
    if str(path).endswith(os.sep) or (os.altsep and str(path).endswith(os.altsep)):  # Path() would drop the slash
        raise Im2VecError(f"{path}: ends with a slash, which names a folder; give a file name")
    if parents:
        make_folder(Path(path).parent)
    try:
        atomic_write(path, raw)
    except OSError as exc:
        raise Im2VecError(f"{path}: cannot write ({exc.strerror or exc})") from None


def make_folder(path: str | os.PathLike) -> Path:
    """Create an output folder (and its parents); a failure is one error line."""
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise Im2VecError(f"{out}: cannot create folder ({exc.strerror or exc})") from None
    return out


@contextlib.contextmanager
def native_stderr_quiet():
    """Point file descriptor 2 at /dev/null while ``sys.stderr`` (our errors, warnings and
    progress) keeps writing to where stderr went: lines that native code and child processes
    write straight to the descriptor (Ray's core worker) stay off the terminal. A no-op where
    ``sys.stderr`` is not descriptor 2 (in process, as under click's test runner)."""
    try:
        real = sys.stderr.fileno() == 2
    except (AttributeError, OSError, ValueError):
        real = False
    if not real:
        yield
        return
    sys.stderr.flush()
    saved = os.dup(2)
    ours, before = os.fdopen(saved, "w", buffering=1, encoding=sys.stderr.encoding, errors="backslashreplace"), sys.stderr
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 2)
    os.close(null)
    sys.stderr = ours
    try:
        yield
    finally:
        ours.flush()
        os.dup2(saved, 2)
        sys.stderr = before
        ours.close()
