"""The runner of the bad-input tables (``test_*_input.py``; docs/RELIABILITY.md lists each case)
and the inputs they share.

Every case runs a real command on a crafted input and checks the documented outcome: ``error``
(exit 1, exactly one ``Error:`` line on stderr, no traceback, no output file and no temp file
left), ``usage`` (exit 2), ``png`` (exit 0 and a drawn PNG), or ``ok`` / ``empty`` (exit 0 and
a valid SVG, with no path for ``empty``). Whatever the outcome, every input is left untouched.
"""

from __future__ import annotations

import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image, ImageOps

from im2vec_cli.cli import cli
from tests.helpers import check_svg

EXE = [sys.executable, "-m", "im2vec_cli"]
SLOW_CASES = {"20000x20000 image"}  # decoded, then refused: seconds of zlib, in `make test-slow`


def table(cases: dict) -> list:
    """The case names of a table as test parameters, the heavy ones marked slow."""
    return [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_CASES else n for n in cases]


def chunk(kind: bytes, data: bytes) -> bytes:
    return len(data).to_bytes(4, "big") + kind + data + zlib.crc32(kind + data).to_bytes(4, "big")


def png_bytes(w: int, h: int, row: bytes, bit_depth: int = 1, color_type: int = 0) -> bytes:
    """A valid PNG built row by row with zlib (so huge images cost no memory here)."""
    comp = zlib.compressobj(9)
    idat = b"".join(comp.compress(b"\x00" + row) for _ in range(h)) + comp.flush()
    ihdr = w.to_bytes(4, "big") + h.to_bytes(4, "big") + bytes([bit_depth, color_type, 0, 0, 0])
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


def save(img: Image.Image, path: Path, **kw) -> Path:
    img.save(path, **kw)
    return path


def glyph_like(size=48) -> Image.Image:
    arr = np.full((size, size), 255, np.uint8)
    arr[size // 4 : 3 * size // 4, size // 3 : 2 * size // 3] = 0
    return Image.fromarray(arr)


def invoke(args, stdin, model_dir):
    """``im2vec ARGS`` in process, with ``--model MODEL_DIR`` added where the command takes one
    and ``--env DIR`` turned into ``IM2VEC_MODELS=DIR``."""
    env = {}
    if "--env" in args:  # IM2VEC_MODELS for this case
        i = args.index("--env")
        env, args = {"IM2VEC_MODELS": args[i + 1]}, args[:i] + args[i + 2:]
    if args[0] not in ("render", "train") and "--model" not in args:
        args = args + ["--model", model_dir]
    return CliRunner().invoke(cli, args, input=stdin, env=env)


def no_output(d: Path):
    leftovers = [p.name for p in d.rglob("*") if p.name.startswith(("out", ".out", ".x")) and p.is_file()]
    assert not leftovers, f"partial output left behind: {leftovers}"


def one_error_line(stderr: str):
    lines = stderr.strip().splitlines()
    assert "Traceback" not in stderr
    assert " object at 0x" not in stderr, stderr  # a Python repr is not a message for the user
    assert sum(line.startswith("Error:") for line in lines) == 1, stderr


def check_case(tmp_path: Path, model_dir, build, expect: str) -> None:
    """Build a case's input in a fresh folder, run it, and check the outcome ``expect``."""
    d = tmp_path / "case"
    d.mkdir()
    args, stdin = build(d, model_dir)
    inputs = {p: p.read_bytes() for p in d.rglob("*") if p.is_file()}
    res = invoke(args, stdin, model_dir)
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)
    for p, data in inputs.items():  # whatever the outcome, every input is untouched
        assert p.is_file() and p.read_bytes() == data, f"{p.name} was changed"
    if expect == "error":
        assert res.exit_code == 1, (res.exit_code, res.output)
        assert len(res.stderr.strip().splitlines()) == 1, res.stderr
        one_error_line(res.stderr)
        no_output(d)
    elif expect == "usage":
        assert res.exit_code == 2, (res.exit_code, res.output)
        one_error_line(res.stderr)
        no_output(d)
    elif expect == "png":
        assert res.exit_code == 0, res.output
        with Image.open(d / "out.png") as im:
            assert im.size == (10, 10) and np.asarray(im.convert("L")).min() < 128  # something was drawn
    else:
        assert res.exit_code == 0, res.output
        svg = (d / "out.svg").read_text()
        src = next(p for p in d.iterdir() if p.name.startswith("x."))
        with Image.open(src) as im:
            w, h = ImageOps.exif_transpose(im).size
        paths = check_svg(svg, w, h)
        assert (len(paths) == 0) == (expect == "empty"), f"{len(paths)} paths"
