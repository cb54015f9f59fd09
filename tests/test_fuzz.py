"""Fuzzing the two parsers that read user files: the image loader and the SVG reader.

Any exception other than ``InputError`` (our one-line error) fails. CI runs a short
profile; ``make fuzz`` runs the long one (``HYPOTHESIS_PROFILE=long``).
"""

from __future__ import annotations

import io
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from im2vec_cli.errors import InputError
from im2vec_cli.files import load_image
from im2vec_cli.vector import from_svg, to_tensors

settings.register_profile("ci", max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("long", max_examples=5000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


def _seed_images() -> list[bytes]:
    rng = np.random.default_rng(0)
    arr = (rng.random((12, 10, 3)) * 255).astype(np.uint8)
    out = []
    for mode, fmt, kw in [("RGB", "PNG", {}), ("L", "PNG", {}), ("RGBA", "PNG", {}), ("P", "GIF", {}),
                          ("RGB", "JPEG", {"quality": 80}), ("1", "PNG", {}), ("CMYK", "JPEG", {}),
                          ("RGB", "BMP", {}), ("RGB", "WEBP", {})]:
        buf = io.BytesIO()
        Image.fromarray(arr).convert(mode).save(buf, format=fmt, **kw)
        out.append(buf.getvalue())
    return out


SEEDS = _seed_images()


@st.composite
def mutated_image(draw):
    data = bytearray(draw(st.sampled_from(SEEDS)))
    for _ in range(draw(st.integers(1, 6))):
        op = draw(st.sampled_from(["flip", "truncate", "insert", "delete", "overwrite_int"]))
        pos = draw(st.integers(0, max(0, len(data) - 1)))
        if op == "flip" and data:
            data[pos] ^= draw(st.integers(1, 255))
        elif op == "truncate":
            del data[pos:]
        elif op == "insert":
            data[pos:pos] = draw(st.binary(min_size=1, max_size=16))
        elif op == "delete":
            del data[pos : pos + draw(st.integers(1, 16))]
        elif op == "overwrite_int":  # sizes and lengths live in 2- and 4-byte big/little-endian fields
            data[pos : pos + 4] = draw(st.integers(0, 2**32 - 1)).to_bytes(4, draw(st.sampled_from(["big", "little"])))
    return bytes(data)


def _only_input_errors(fn, data):
    try:
        out = fn(data)
    except InputError as exc:
        assert "\n" not in str(exc)
        return None
    return out


@given(st.one_of(st.binary(max_size=300), mutated_image()))
def test_image_loader_raises_only_input_error(data):
    img = _only_input_errors(lambda b: load_image("<fuzz>", b), data)
    if img is not None:
        assert img.dim() == 3 and img.shape[0] == 3
        assert bool(((img >= 0) & (img <= 1)).all())


SVG_SEED = (
    '<svg xmlns="http://www.w3.org/2000/svg" width="20" height="20" viewBox="0 0 20 20">'
    '<path d="M 2 2 C 5 1 9 1 12 2 C 14 6 14 10 12 14 C 8 15 4 15 2 14 Z M 5 5 C 6 5 7 5 8 5 C 8 6 8 7 8 8 '
    'C 7 8 6 8 5 8 Z" fill="#102030" fill-rule="evenodd" stroke="none"/></svg>'
)

_TOKENS = ["M", "C", "L", "Z", "z", "m", "c", "H", "Q", "A", "1", "-2.5", "1e3", "1e400", "nan", "inf", ".", "-",
           "0", "3.", ",", " "]


@st.composite
def mutated_svg(draw):
    choice = draw(st.integers(0, 2))
    if choice == 0:  # path data made of random tokens
        d = " ".join(draw(st.lists(st.sampled_from(_TOKENS), max_size=40)))
        vb = draw(st.sampled_from(["0 0 20 20", "0 0 0 0", "1 0 20 20", "0 0 -5 5", "0 0 nan 5", "0 0 20", "a b c d",
                                   "0,0,20,20", "0 0 1e400 5"]))
        rule = draw(st.sampled_from(["nonzero", "evenodd", "bogus", ""]))
        fill = draw(st.sampled_from(["#000", "#123456", "red", "none", "#12345", "url(#x)"]))
        return (f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="{vb}"><path d="{d}" fill="{fill}" '
                f'fill-rule="{rule}"/></svg>')
    text = SVG_SEED
    if choice == 1:  # character-level mutations of a valid file
        chars = list(text)
        for _ in range(draw(st.integers(1, 8))):
            pos = draw(st.integers(0, len(chars) - 1))
            chars[pos] = draw(st.characters(codec="utf-8"))
        return "".join(chars)
    cut = draw(st.integers(0, len(text)))  # truncation plus junk
    return text[:cut] + draw(st.text(max_size=20))


@given(st.one_of(mutated_svg(), st.text(max_size=200), st.binary(max_size=200)))
@settings(suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
def test_svg_reader_raises_only_input_error(text):
    def read(t):
        im = from_svg(t)
        if im.shapes and any(s.contours for s in im.shapes):
            pts, cols, _ = to_tensors(im)
            assert pts.shape[-1] == 2 and bool(np.isfinite(pts.numpy()).all())
        return im

    _only_input_errors(read, text)


@pytest.mark.parametrize("seed", range(len(SEEDS)))
def test_seed_images_load(seed):
    """The fuzz seeds themselves are valid (so the mutations start from real files)."""
    assert load_image("<seed>", SEEDS[seed]).shape == (3, 12, 10)


NUMBER_TEXT = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.integers().map(str),
                        st.sampled_from(["nan", "inf", "-inf", "1e309", "", " ", "0x10", "1_0", "١"]), st.text(max_size=8))


@given(NUMBER_TEXT)
def test_option_parsers_accept_only_what_they_say(text):
    """Every float option refuses NaN and infinities; seeds stay in [0, 2^32); --segments and
    --sweep take only their documented forms. Anything else is click's usage error (exit 2)."""
    import math

    import click

    from im2vec_cli.cli.options import SEED, Finite, parse_segments, parse_sweep

    for param, check in ((Finite(0), lambda v: math.isfinite(v) and v >= 0),
                         (Finite(0, min_open=True), lambda v: math.isfinite(v) and v > 0),
                         (SEED, lambda v: 0 <= v < 2**32)):
        try:
            value = param.convert(text, None, None)
        except click.BadParameter:
            continue
        assert check(value), (text, value)
    for parse, check in ((parse_segments, lambda v: v == "auto" or (isinstance(v, int) and 1 <= v <= 200)),
                         (parse_sweep, lambda v: 1 <= v[0] <= v[-1] <= 256)):
        try:
            assert check(parse(text))
        except click.BadParameter:
            pass


@given(st.sampled_from(["1e308", "-1e308", "1e6", "999999", "1e7", "nan", "inf", "0", "-0", "1e-320", "12"]),
       st.sampled_from(["0 0 10 10", "0 0 1e7 10", "0 0 0 10", "0 0 -5 5", "0 0 nan 10", "1e308 0 10 10", ""]),
       st.integers(0, 3))
def test_svg_size_checks(coordinate, view_box, repeat):
    """Coordinates and canvases at and past the bounds: an ``InputError`` or a VectorImage whose
    every number is finite and within the documented bound, never anything else."""
    from im2vec_cli.vector.read import MAX_COORD

    box = f' viewBox="{view_box}"' if view_box else ' width="10" height="10"'
    d = "M 1 1 " + f"L {coordinate} 2 L 3 {coordinate} " * (1 + repeat) + "Z"
    text = f'<svg xmlns="http://www.w3.org/2000/svg"{box}><path d="{d}"/></svg>'
    try:
        im = from_svg(text)
    except InputError:
        return
    assert 0 < im.width <= MAX_COORD and 0 < im.height <= MAX_COORD
    for s in im.shapes:
        for c in s.contours:
            assert np.isfinite(c).all() and (np.abs(c) <= MAX_COORD).all()
