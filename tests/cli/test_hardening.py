"""Bad input, faults and determinism (issue "Hardening"). docs/RELIABILITY.md lists each case.

Every case in ``CASES`` runs a real command on a crafted input and checks the documented
outcome: ``error`` (exit 1, exactly one ``Error:`` line on stderr, no traceback, no output
file and no temp file left), ``usage`` (exit 2), or ``ok`` / ``empty`` (exit 0 and a valid
SVG, with no path for ``empty``).
"""

from __future__ import annotations

import errno
import io
import json
import os
import shutil
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from im2vec_cli.cli import cli
from tests.helpers import TINY, check_svg, make_tiny_model, png

EXE = [sys.executable, "-m", "im2vec_cli"]


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory):
    return make_tiny_model(tmp_path_factory.mktemp("m") / "tiny")


def _chunk(kind: bytes, data: bytes) -> bytes:
    return len(data).to_bytes(4, "big") + kind + data + zlib.crc32(kind + data).to_bytes(4, "big")


def _png_bytes(w: int, h: int, row: bytes, bit_depth: int = 1, color_type: int = 0) -> bytes:
    """A valid PNG built row by row with zlib (so huge images cost no memory here)."""
    comp = zlib.compressobj(9)
    idat = b"".join(comp.compress(b"\x00" + row) for _ in range(h)) + comp.flush()
    ihdr = w.to_bytes(4, "big") + h.to_bytes(4, "big") + bytes([bit_depth, color_type, 0, 0, 0])
    return b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", idat) + _chunk(b"IEND", b"")


def _save(img: Image.Image, path: Path, **kw) -> Path:
    img.save(path, **kw)
    return path


def _glyph_like(size=48) -> Image.Image:
    arr = np.full((size, size), 255, np.uint8)
    arr[size // 4 : 3 * size // 4, size // 3 : 2 * size // 3] = 0
    return Image.fromarray(arr)


# ---- input builders: each returns (args after the model options, stdin bytes or None)


def in_missing(d, m):
    return ["vectorize", str(d / "nope.png"), "-o", str(d / "out.svg")], None


def in_zero_bytes(d, m):
    (d / "x.png").write_bytes(b"")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_text_named_png(d, m):
    (d / "x.png").write_text("this is not an image\n")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_truncated_png(d, m):
    (d / "x.png").write_bytes(Path(png(d / "full.png", 40, 40)).read_bytes()[:70])
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_bad_crc(d, m):
    raw = bytearray(Path(png(d / "full.png", 40, 40)).read_bytes())
    raw[29] ^= 0xFF  # the IHDR chunk's CRC (8 signature + 8 header + 13 data = byte 29)
    (d / "x.png").write_bytes(bytes(raw))
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_png_signature_then_junk(d, m):
    (d / "x.png").write_bytes(b"\x89PNG\r\n\x1a\n" + os.urandom(200))
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_corrupt_idat(d, m):
    (d / "x.png").write_bytes(_png_bytes(40, 40, b"\xff" * 5)[:33] + _chunk(b"IDAT", b"\x78\x9c" + os.urandom(40))
                              + _chunk(b"IEND", b""))
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_one_pixel(d, m):
    _save(Image.new("L", (1, 1), 0), d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_sliver(d, m):
    _save(Image.new("L", (2, 500), 0), d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_20000_square(d, m):
    (d / "x.png").write_bytes(_png_bytes(20000, 20000, b"\xff" * 2500))  # a real, complete 1-bit image
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_decompression_bomb(d, m):
    # a header claiming 100000 x 100000 pixels in front of a few bytes of data
    ihdr = (100000).to_bytes(4, "big") * 2 + bytes([8, 0, 0, 0, 0])
    (d / "x.png").write_bytes(b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", zlib.compress(b"\0" * 99))
                              + _chunk(b"IEND", b""))
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_gif_bomb(d, m):
    # GIF logical screen of 65535 x 65535 with a tiny frame
    gif = io.BytesIO()
    Image.new("P", (8, 8)).save(gif, format="GIF")
    raw = bytearray(gif.getvalue())
    raw[6:10] = (65535).to_bytes(2, "little") * 2
    (d / "x.gif").write_bytes(bytes(raw))
    return ["vectorize", str(d / "x.gif"), "-o", str(d / "out.svg")], None


def in_truncated_jpg(d, m):
    buf = io.BytesIO()
    _glyph_like().convert("RGB").save(buf, format="JPEG")
    (d / "x.jpg").write_bytes(buf.getvalue()[:200])
    return ["vectorize", str(d / "x.jpg"), "-o", str(d / "out.svg")], None


def in_broken_symlink(d, m):
    os.symlink(d / "gone.png", d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_empty_folder(d, m):
    (d / "in").mkdir()
    (d / "in" / "notes.txt").write_text("no images here")
    return ["vectorize", str(d / "in"), "-o", str(d / "outdir")], None


def in_16bit_gray(d, m):
    arr = (np.asarray(_glyph_like(), np.uint16) * 257).astype(np.uint16)
    img = Image.fromarray(arr)
    assert img.mode == "I;16"
    _save(img, d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_palette_transparency(d, m):
    img = _glyph_like().convert("P")
    img.info["transparency"] = 255  # white (index 255 in the grey palette) is transparent
    _save(img, d / "x.png", transparency=255)
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_cmyk_jpg(d, m):
    _save(_glyph_like().convert("CMYK"), d / "x.jpg", format="JPEG")
    return ["vectorize", str(d / "x.jpg"), "-o", str(d / "out.svg")], None


def in_animated_gif(d, m):
    frames = [_glyph_like(), _glyph_like().transpose(Image.Transpose.ROTATE_90)]
    frames[0].save(d / "x.gif", save_all=True, append_images=frames[1:], duration=100, loop=0)
    return ["vectorize", str(d / "x.gif"), "-o", str(d / "out.svg")], None


def in_animated_png(d, m):
    frames = [_glyph_like().convert("RGB"), Image.new("RGB", (48, 48), "black")]
    frames[0].save(d / "x.png", save_all=True, append_images=frames[1:], duration=100)
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_exif_rotated_jpg(d, m):
    img = Image.new("RGB", (60, 30), "white")
    exif = Image.Exif()
    exif[0x0112] = 6  # orientation: rotate 90 degrees to display -> 30 x 60
    img.save(d / "x.jpg", exif=exif)
    return ["vectorize", str(d / "x.jpg"), "-o", str(d / "out.svg")], None


def in_all_white(d, m):
    _save(Image.new("RGB", (50, 40), "white"), d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_fully_transparent(d, m):
    _save(Image.new("RGBA", (50, 40), (10, 20, 30, 0)), d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_all_black(d, m):
    _save(Image.new("L", (50, 40), 0), d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_stdin_empty(d, m):
    return ["vectorize", "-", "-o", str(d / "out.svg")], b""


def in_stdin_junk(d, m):
    return ["vectorize", "-", "-o", str(d / "out.svg")], b"GIF89a" + b"\0" * 20


def in_unknown_model(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", "no-such-model"], None


def _model_copy(d, m):
    dst = d / "model"
    dst.mkdir()
    for f in Path(m).iterdir():
        (dst / f.name).write_bytes(f.read_bytes())
    return dst


def in_model_missing_weights(d, m):
    dst = _model_copy(d, m)
    (dst / "model.safetensors").unlink()
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(dst)], None


def in_model_truncated_weights(d, m):
    dst = _model_copy(d, m)
    w = dst / "model.safetensors"
    w.write_bytes(w.read_bytes()[: w.stat().st_size // 2])
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(dst)], None


def in_model_nan_weights(d, m):
    from safetensors.torch import load_file, save_file

    dst = _model_copy(d, m)
    state = load_file(str(dst / "model.safetensors"))
    key = sorted(k for k, v in state.items() if v.is_floating_point())[0]
    state[key] = state[key].clone().fill_(float("nan"))
    save_file(state, str(dst / "model.safetensors"))
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(dst)], None


def in_model_config_wrong_version(d, m):
    dst = _model_copy(d, m)
    cfg = json.loads((dst / "config.json").read_text())
    cfg["format_version"] = 99
    (dst / "config.json").write_text(json.dumps(cfg))
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(dst)], None


def in_model_config_not_json(d, m):
    dst = _model_copy(d, m)
    (dst / "config.json").write_text("{ not json")
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(dst)], None


def in_model_config_mismatch(d, m):
    dst = _model_copy(d, m)
    cfg = json.loads((dst / "config.json").read_text())
    cfg["latent"] = TINY.latent * 2  # the weights were trained with another latent size
    (dst / "config.json").write_text(json.dumps(cfg))
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(dst)], None


def in_latent_nan(d, m):
    np.save(d / "z.npy", np.full(TINY.latent, np.nan, np.float32))
    return ["interpolate", png(d / "a.png"), str(d / "z.npy"), "-o", str(d / "outdir")], None


def in_latent_wrong_size(d, m):
    np.save(d / "z.npy", np.zeros(TINY.latent + 3, np.float32))
    return ["interpolate", png(d / "a.png"), str(d / "z.npy"), "-o", str(d / "outdir")], None


def in_latent_pickle(d, m):
    np.save(d / "z.npy", np.array([{"evil": 1}], dtype=object), allow_pickle=True)
    return ["interpolate", png(d / "a.png"), str(d / "z.npy"), "-o", str(d / "outdir")], None


def in_latent_json_garbage(d, m):
    (d / "z.json").write_text('{"latent": "abc"}\n')
    return ["interpolate", png(d / "a.png"), str(d / "z.json"), "-o", str(d / "outdir")], None


def in_output_parent_missing(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "no" / "such" / "dir" / "out.svg")], None


def in_output_is_directory(d, m):
    (d / "out.png").mkdir()
    return _render(d, _svg("M 1 1 L 9 1 L 9 9 Z"))


def _render(d, svg_text):
    (d / "x.svg").write_text(svg_text)
    return ["render", str(d / "x.svg"), "-o", str(d / "out.png")], None


def _svg(path_d, view_box="0 0 10 10"):
    return f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="{view_box}"><path d="{path_d}"/></svg>'


def in_render_not_xml(d, m):
    return _render(d, "<svg <<<")


def in_render_bad_viewbox(d, m):
    return _render(d, _svg("M 1 1 L 9 1 L 9 9 Z", "0 0 ten 10"))


def in_unknown_option(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--frobnicate"], None


def in_segments_zero(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--segments", "0"], None


def in_folder_to_stdout(d, m):
    (d / "in").mkdir()
    png(d / "in" / "a.png")
    return ["vectorize", str(d / "in"), "-o", "-"], None


def in_unknown_device(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--device", "tpu:7"], None


def in_sample_zero(d, m):
    return ["sample", "--n", "0", "-o", str(d / "outdir")], None


def in_render_relative_commands(d, m):
    return _render(d, _svg("m 1 1 l 5 0 l 0 5 z"))


def in_render_open_path(d, m):
    return _render(d, _svg("M 1 1 L 9 1 L 9 9"))  # filled as SVG fills it: closed back to the start


def in_render_font_outline(d, m):
    # an ordinary font outline as exported by a font editor: H, V, Q, T, S, relative commands
    return _render(d, _svg("M1 1H9V3h-6v2q2 0 2 2t-2 2s-1 0 -1 -1z"))


def in_render_stroke(d, m):
    return _render(d, _svg('M 1 2 L 8 2 L 8 9" fill="none" stroke="black" stroke-width="2'))  # its filled outline


def in_render_semi_transparent_stroke(d, m):
    return _render(d, _svg('M 1 1 L 9 1 L 9 9 Z" stroke="red" stroke-opacity="0.5'))


def in_render_gradient(d, m):
    return _render(d, '<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10"><defs><linearGradient id="g">'
                      '<stop offset="0" stop-color="red"/></linearGradient></defs>'
                      '<path d="M 1 1 L 9 1 L 9 9 Z" fill="url(#g)"/></svg>')


def in_render_text(d, m):
    return _render(d, '<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10"><text x="1" y="8">a</text></svg>')


def in_render_huge_coordinates(d, m):
    return _render(d, _svg("M 1e308 1 L 9 1 L 9 9 Z"))


def in_render_million_segments(d, m):
    return _render(d, _svg("M 1 1 " + "L 2 2 L 1 1 " * 500_000 + "Z"))


def in_render_use_bomb(d, m):
    parts = ['<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" viewBox="0 0 10 10">'
             '<defs><path id="g0" d="M1 1 L2 1 L2 2 Z"/>']
    for i in range(1, 8):  # 10^7 paths once expanded
        parts.append(f'<g id="g{i}">' + f'<use xlink:href="#g{i - 1}"/>' * 10 + "</g>")
    return _render(d, "".join(parts) + '</defs><use xlink:href="#g7"/></svg>')


def in_render_use_cycle(d, m):
    return _render(d, '<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" '
                      'viewBox="0 0 10 10"><g id="a"><path d="M1 1 L9 1 L9 9 Z"/><use xlink:href="#a"/></g></svg>')


def in_render_deep_nesting(d, m):
    return _render(d, '<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10">' + "<g>" * 5000
                   + '<path d="M1 1 L9 1 L9 9 Z"/>' + "</g>" * 5000 + "</svg>")


def in_render_huge_viewbox(d, m):
    return _render(d, _svg("M 1 1 L 9 1 L 9 9 Z", "0 0 100000 100000"))


def in_render_scale_1000(d, m):
    args, stdin = _render(d, _svg("M 1 1 L 9 1 L 9 9 Z", "0 0 64 64"))
    return args + ["--scale", "1000"], stdin


def in_render_scale_nan(d, m):
    args, stdin = _render(d, _svg("M 1 1 L 9 1 L 9 9 Z"))
    return args + ["--scale", "nan"], stdin


def in_render_tau_nan(d, m):
    args, stdin = _render(d, _svg("M 1 1 L 9 1 L 9 9 Z"))
    return args + ["--tau", "nan"], stdin


def in_render_onto_its_input(d, m):
    (d / "x.svg").write_text(_svg("M 1 1 L 9 1 L 9 9 Z"))
    return ["render", str(d / "x.svg"), "-o", str(d / "x.svg")], None


def vectorize_with(*option):
    """A case builder: ``vectorize`` of a good PNG with ``option`` added (a bad option value)."""
    def build(d, m):
        return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), *option], None

    return build


in_quality_nan = vectorize_with("--quality", "nan")
in_tolerance_nan = vectorize_with("--tolerance", "nan")
in_tolerance_negative = vectorize_with("--tolerance", "-1")
in_tolerance_zero = vectorize_with("--tolerance", "0")
in_colors_zero = vectorize_with("--colors", "0")
in_colors_too_many = vectorize_with("--colors", "1000")
in_max_paths_zero = vectorize_with("--max-paths", "0")
in_parts_unknown = vectorize_with("--parts", "some")
in_simplify_nan = vectorize_with("--simplify", "nan")


def in_temperature_inf(d, m):
    return ["sample", "--temperature", "inf", "-o", str(d / "outdir")], None


def in_seed_beyond_64_bits(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--seed", str(2**70)], None


def in_negative_seed(d, m):
    return ["sample", "--seed", "-1", "-o", str(d / "outdir")], None


def in_output_is_the_input(d, m):
    return ["vectorize", png(d / "x.png"), "-o", str(d / "x.png")], None


def in_output_is_the_input_through_a_link(d, m):
    src = png(d / "x.png")
    (d / "link.svg").symlink_to(src)
    return ["vectorize", src, "-o", str(d / "link.svg")], None


def in_output_is_the_input_hard_link(d, m):
    src = png(d / "x.png")
    os.link(src, d / "hard.svg")
    return ["vectorize", src, "-o", str(d / "hard.svg")], None


def in_empty_input_path(d, m):
    return ["vectorize", "", "-o", str(d / "out.svg")], None


def in_empty_output_path(d, m):
    return ["vectorize", png(d / "a.png"), "-o", ""], None


def in_interpolate_empty_second(d, m):
    return ["interpolate", png(d / "a.png"), "", "-o", str(d / "outdir")], None


def in_interpolate_onto_its_input(d, m):
    (d / "outdir").mkdir()
    src = png(d / "outdir" / "contact.png")
    return ["interpolate", src, png(d / "b.png"), "-o", str(d / "outdir")], None


def in_stdin_endless(d, m):
    from im2vec_cli import files

    return ["vectorize", "-", "-o", str(d / "out.svg")], b"\0" * (files.MAX_INPUT_BYTES + 1)


def in_models_env_missing(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", "fonts", "--env",
            str(d / "no-such-folder")], None


def _config(d, text):
    (d / "c.json").write_text(text)
    (d / "data").mkdir()
    png(d / "data" / "a.png", 32, 32)
    return ["train", str(d / "data"), "--config", str(d / "c.json"), "--out", str(d / "outrun")], None


def in_config_null(d, m):
    return _config(d, "null")


def in_config_list(d, m):
    return _config(d, "[1, 2, 3]")


def in_config_model_not_object(d, m):
    return _config(d, '{"model": [1]}')


def in_config_segments_zero(d, m):
    return _config(d, '{"model": {"segments": 0}}')


def in_config_lr_negative(d, m):
    return _config(d, '{"train": {"lr": -1}}')


def in_model_config_null(d, m):
    bad = d / "model"
    shutil.copytree(m, bad)
    (bad / "config.json").write_text("null")
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(bad)], None


def in_model_config_out_of_range(d, m):
    bad = d / "model"
    shutil.copytree(m, bad)
    cfg = json.loads((bad / "config.json").read_text())
    cfg["paths"] = 0
    (bad / "config.json").write_text(json.dumps(cfg))
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(bad)], None


# name -> (builder, expected outcome, whether the command takes --model)
CASES = {
    "missing file": (in_missing, "error"),
    "zero-byte file": (in_zero_bytes, "error"),
    "text file named .png": (in_text_named_png, "error"),
    "truncated PNG": (in_truncated_png, "error"),
    "corrupt chunk CRC": (in_bad_crc, "error"),
    "PNG signature then junk": (in_png_signature_then_junk, "error"),
    "corrupt compressed data": (in_corrupt_idat, "error"),
    "1x1 image": (in_one_pixel, "error"),
    "2x500 sliver": (in_sliver, "error"),
    "20000x20000 image": (in_20000_square, "error"),
    "decompression bomb (PNG)": (in_decompression_bomb, "error"),
    "decompression bomb (GIF screen)": (in_gif_bomb, "error"),
    "truncated JPG": (in_truncated_jpg, "error"),
    "broken symlink": (in_broken_symlink, "error"),
    "folder without images": (in_empty_folder, "error"),
    "16-bit grayscale": (in_16bit_gray, "ok"),
    "palette with transparency": (in_palette_transparency, "ok"),
    "CMYK JPG": (in_cmyk_jpg, "ok"),
    "animated GIF": (in_animated_gif, "ok"),
    "animated PNG": (in_animated_png, "ok"),
    "EXIF-rotated JPG": (in_exif_rotated_jpg, "empty"),
    "all-white": (in_all_white, "empty"),
    "fully transparent": (in_fully_transparent, "empty"),
    "all-black": (in_all_black, "ok"),
    "stdin empty": (in_stdin_empty, "error"),
    "stdin not an image": (in_stdin_junk, "error"),
    "unknown model name": (in_unknown_model, "error"),
    "model: missing weights": (in_model_missing_weights, "error"),
    "model: truncated weights": (in_model_truncated_weights, "error"),
    "model: NaN weights": (in_model_nan_weights, "error"),
    "model: config of another version": (in_model_config_wrong_version, "error"),
    "model: config not JSON": (in_model_config_not_json, "error"),
    "model: config does not match weights": (in_model_config_mismatch, "error"),
    "latent with NaN": (in_latent_nan, "error"),
    "latent of the wrong size": (in_latent_wrong_size, "error"),
    "latent .npy holding a pickle": (in_latent_pickle, "error"),
    "latent JSON not numbers": (in_latent_json_garbage, "error"),
    "output folder missing": (in_output_parent_missing, "error"),
    "output path is a directory": (in_output_is_directory, "error"),
    "SVG: not XML": (in_render_not_xml, "error"),
    "SVG: relative commands": (in_render_relative_commands, "png"),
    "SVG: open path": (in_render_open_path, "png"),
    "SVG: font outline (H V Q T S, relative)": (in_render_font_outline, "png"),
    "SVG: stroke": (in_render_stroke, "png"),
    "SVG: semi-transparent stroke": (in_render_semi_transparent_stroke, "error"),
    "SVG: gradient fill": (in_render_gradient, "error"),
    "SVG: text": (in_render_text, "error"),
    "SVG: coordinates of 1e308": (in_render_huge_coordinates, "error"),
    "SVG: 1,000,000 segments": (in_render_million_segments, "error"),
    "SVG: viewBox of 100000 x 100000": (in_render_huge_viewbox, "error"),
    "SVG: <use> bomb": (in_render_use_bomb, "error"),
    "SVG: <use> cycle": (in_render_use_cycle, "error"),
    "SVG: 5000 nested groups": (in_render_deep_nesting, "error"),
    "render --scale 1000": (in_render_scale_1000, "error"),
    "render --scale nan": (in_render_scale_nan, "usage"),
    "render --tau nan": (in_render_tau_nan, "usage"),
    "render onto its input": (in_render_onto_its_input, "usage"),
    "--quality nan": (in_quality_nan, "usage"),
    "--simplify nan": (in_simplify_nan, "usage"),
    "--tolerance nan": (in_tolerance_nan, "usage"),
    "--tolerance -1": (in_tolerance_negative, "usage"),
    "--tolerance 0": (in_tolerance_zero, "usage"),
    "--colors 0": (in_colors_zero, "usage"),
    "--colors 1000": (in_colors_too_many, "usage"),
    "--max-paths 0": (in_max_paths_zero, "usage"),
    "--parts some": (in_parts_unknown, "usage"),
    "--temperature inf": (in_temperature_inf, "usage"),
    "seed beyond 64 bits": (in_seed_beyond_64_bits, "usage"),
    "negative seed": (in_negative_seed, "usage"),
    "output is the input": (in_output_is_the_input, "usage"),
    "output is the input (symlink)": (in_output_is_the_input_through_a_link, "usage"),
    "output is the input (hard link)": (in_output_is_the_input_hard_link, "usage"),
    "empty input path": (in_empty_input_path, "usage"),
    "empty output path": (in_empty_output_path, "usage"),
    "interpolate with an empty path": (in_interpolate_empty_second, "usage"),
    "interpolate onto its input": (in_interpolate_onto_its_input, "usage"),
    "stdin over 256 MiB": (in_stdin_endless, "error"),
    "IM2VEC_MODELS missing": (in_models_env_missing, "error"),
    "train config: null": (in_config_null, "error"),
    "train config: a list": (in_config_list, "error"),
    "train config: model section not an object": (in_config_model_not_object, "error"),
    "train config: segments 0": (in_config_segments_zero, "error"),
    "train config: negative lr": (in_config_lr_negative, "error"),
    "model: config null": (in_model_config_null, "error"),
    "model: config out of range": (in_model_config_out_of_range, "error"),
    "SVG: bad viewBox": (in_render_bad_viewbox, "error"),
    "unknown option": (in_unknown_option, "usage"),
    "--segments 0": (in_segments_zero, "usage"),
    "folder to stdout": (in_folder_to_stdout, "usage"),
    "unknown device": (in_unknown_device, "error"),
    "sample --n 0": (in_sample_zero, "usage"),
}


def _invoke(args, stdin, model_dir):
    env = {}
    if "--env" in args:  # IM2VEC_MODELS for this case
        i = args.index("--env")
        env, args = {"IM2VEC_MODELS": args[i + 1]}, args[:i] + args[i + 2:]
    if args[0] not in ("render", "train") and "--model" not in args:
        args = args + ["--model", model_dir]
    return CliRunner().invoke(cli, args, input=stdin, env=env)


def _no_output(d: Path):
    leftovers = [p.name for p in d.rglob("*") if p.name.startswith(("out", ".out", ".x")) and p.is_file()]
    assert not leftovers, f"partial output left behind: {leftovers}"


def _one_error_line(stderr: str):
    lines = stderr.strip().splitlines()
    assert "Traceback" not in stderr
    assert " object at 0x" not in stderr, stderr  # a Python repr is not a message for the user
    assert sum(line.startswith("Error:") for line in lines) == 1, stderr


@pytest.mark.parametrize("name", list(CASES))
def test_bad_input_table(tmp_path, model_dir, name):
    build, expect = CASES[name]
    d = tmp_path / "case"
    d.mkdir()
    args, stdin = build(d, model_dir)
    inputs = {p: p.read_bytes() for p in d.rglob("*") if p.is_file()}
    res = _invoke(args, stdin, model_dir)
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)
    for p, data in inputs.items():  # whatever the outcome, every input is untouched
        assert p.is_file() and p.read_bytes() == data, f"{p.name} was changed"
    if expect == "error":
        assert res.exit_code == 1, (res.exit_code, res.output)
        assert len(res.stderr.strip().splitlines()) == 1, res.stderr
        _one_error_line(res.stderr)
        _no_output(d)
    elif expect == "usage":
        assert res.exit_code == 2, (res.exit_code, res.output)
        _one_error_line(res.stderr)
        _no_output(d)
    elif expect == "png":
        assert res.exit_code == 0, res.output
        with Image.open(d / "out.png") as im:
            assert im.size == (10, 10) and np.asarray(im.convert("L")).min() < 128  # something was drawn
    else:
        assert res.exit_code == 0, res.output
        svg = (d / "out.svg").read_text()
        src = next(p for p in d.iterdir() if p.name.startswith("x."))
        with Image.open(src) as im:
            from PIL import ImageOps

            w, h = ImageOps.exif_transpose(im).size
        paths = check_svg(svg, w, h)
        assert (len(paths) == 0) == (expect == "empty"), f"{len(paths)} paths"


def test_all_black_is_one_canvas_square(tmp_path, model_dir):
    args, _ = in_all_black(tmp_path, model_dir)
    assert _invoke(args, None, model_dir).exit_code == 0
    from im2vec_cli.vector import rasterize_svg

    img = rasterize_svg((tmp_path / "out.svg").read_text(), 50, 40)
    assert img.max() < 0.01  # every pixel black, as in the input


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


@pytest.mark.slow  # 1,000 files through worker processes
def test_batch_of_1000_with_5_percent_bad(tmp_path, model_dir, monkeypatch):
    """Every good file is written (refined, in worker processes: the defaults for a folder this
    large), every bad one is listed, exit 1; images are streamed."""
    import im2vec_cli.parallel as parallel
    import im2vec_cli.runtime as runtime

    jobs, real = [], parallel.vectorize_chunks
    monkeypatch.setattr(parallel, "vectorize_chunks", lambda *a, **kw: jobs.append(kw) or real(*a, **kw))
    monkeypatch.setattr(runtime, "free_cores", lambda: os.cpu_count() or 1)  # a quiet machine, whatever runs beside
    d = tmp_path / "in"
    d.mkdir()
    good = _glyph_like(32)
    bad = set(range(0, 1000, 20))  # 50 bad files
    for i in range(1000):
        p = d / f"g{i:04d}.png"
        if i in bad:
            p.write_bytes(b"\x89PNG broken" if i % 40 else b"")
        else:
            good.save(p)
    res = CliRunner().invoke(cli, ["vectorize", str(d), "-o", str(tmp_path / "out"), "--model", model_dir])
    assert res.exit_code == 1
    written = sorted(p.stem for p in (tmp_path / "out").glob("*.svg"))
    assert written == [f"g{i:04d}" for i in range(1000) if i not in bad]
    errors = [line for line in res.stderr.splitlines() if line.startswith("Error:")]
    assert len(errors) == 51 and errors[-1] == "Error: 50 of 1000 inputs failed"
    assert {line.split(":")[1].strip().rsplit("/", 1)[-1] for line in errors[:-1]} == {
        f"g{i:04d}.png" for i in bad}
    expected = min(os.cpu_count() or 1, 8)
    assert (jobs[0]["jobs"], jobs[0]["options"].refine, jobs[0]["options"].compile) == (expected, True, False) \
        if expected > 1 else not jobs


@pytest.mark.parametrize("refine", [True, False])
def test_batch_streams_in_chunks(tmp_path, model_dir, monkeypatch, refine):
    """At most one chunk of images is alive at any time: one refinement batch per chunk by
    default, one forward pass per chunk with --no-refine."""
    import im2vec_cli.cli.convert as cli_mod
    import im2vec_cli.infer as infer
    import im2vec_cli.refine as refinement

    d = tmp_path / "in"
    d.mkdir()
    for i in range(70):
        _glyph_like(32).save(d / f"g{i:03d}.png")
    sizes = []
    mod, name = (refinement, "refine_batch") if refine else (infer, "vectorize")
    real = getattr(mod, name)
    monkeypatch.setattr(mod, name, lambda model, images, **kw: sizes.append(len(images)) or real(model, images, **kw))
    res = CliRunner().invoke(cli, ["vectorize", str(d), "-o", str(tmp_path / "out"), "--model", model_dir, "-j", "1"]
                             + ([] if refine else ["--no-refine"]))
    assert res.exit_code == 0 and sum(sizes) == 70 and max(sizes) == cli_mod.VECTORIZE_CHUNK
    assert len(list((tmp_path / "out").glob("*.svg"))) == 70


def test_worker_processes_write_what_one_process_writes(tmp_path, model_dir):
    """`-j 2` (chunks refined in two worker processes) writes byte for byte what `-j 1` writes,
    on a folder of several image sizes (several refinement groups)."""
    d = tmp_path / "in"
    d.mkdir()
    for i in range(12):
        _glyph_like(30 + i % 4).save(d / f"g{i:02d}.png")
    outs = []
    for jobs in ("1", "2"):
        res = CliRunner().invoke(cli, ["vectorize", str(d), "-o", str(tmp_path / jobs), "--model", model_dir, "-j", jobs])
        assert res.exit_code == 0, res.output
        outs.append({p.name: p.read_text() for p in (tmp_path / jobs).glob("*.svg")})
    assert len(outs[0]) == 12 and outs[0] == outs[1]


@pytest.mark.slow  # a real SIGINT into 1,200 files, twice
@pytest.mark.parametrize("jobs", ["1", "2"])
def test_ctrl_c_in_a_real_process_leaves_only_complete_svgs(tmp_path, model_dir, jobs):
    """A real SIGINT (what Ctrl-C sends) while a folder is being refined, once the first chunk
    is written: exit 130, one line, every SVG on disk complete, no temp file, the rest absent."""
    import signal
    import time

    d = tmp_path / "in"
    d.mkdir()
    n = 1200  # seconds of work after the first chunk, so that a busy machine cannot finish it before the signal
    for i in range(n):
        _glyph_like(32 + i % 3).save(d / f"g{i:04d}.png")
    out = tmp_path / "out"
    proc = subprocess.Popen(EXE + ["vectorize", str(d), "-o", str(out), "--model", model_dir, "--jobs", jobs],
                            stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 240
    while time.time() < deadline and not list(out.glob("*.svg")) and proc.poll() is None:
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    written = sorted(out.glob("*.svg"))
    assert proc.returncode == 130, (err, f"{len(written)} of {n} written")
    assert "Traceback" not in err and err.strip().splitlines()[-1] == "Interrupted."
    assert 0 < len(written) < n
    for p in written:
        check_svg(p.read_text(), 32 + int(p.stem[1:]) % 3, 32 + int(p.stem[1:]) % 3)
    assert [p.name for p in out.iterdir() if p.suffix != ".svg"] == []


def test_determinism_byte_identical(tmp_path, model_dir):
    """Same input, model and seed: byte-identical SVGs from separate processes."""
    src = png(tmp_path / "a.png", 37, 29)
    outs = []
    for i in range(2):
        out = tmp_path / f"o{i}.svg"
        r = subprocess.run(EXE + ["vectorize", src, "-o", str(out), "--model", model_dir, "--seed", "3"],
                           capture_output=True)
        assert r.returncode == 0, r.stderr
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]
    samples = []
    for i in range(2):
        r = subprocess.run(EXE + ["sample", "--n", "3", "-o", str(tmp_path / f"s{i}"), "--model", model_dir,
                                  "--seed", "5"], capture_output=True)
        assert r.returncode == 0, r.stderr
        samples.append([p.read_bytes() for p in sorted((tmp_path / f"s{i}").glob("*.svg"))])
    assert samples[0] == samples[1]


def test_reliability_doc_lists_every_case():
    doc = (Path(__file__).resolve().parents[2] / "docs" / "RELIABILITY.md").read_text()
    rows = {line.split("|")[1].strip(): line.split("|")[2].strip() for line in doc.splitlines()
            if line.startswith("| ") and line.count("|") >= 4}
    for name, (_, expect) in CASES.items():
        assert rows.get(name) == expect, name


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


@pytest.mark.parametrize("refine", ["--refine", "--no-refine"])
def test_interrupt_keeps_exactly_the_finished_svgs(tmp_path, model_dir, monkeypatch, refine):
    """Ctrl-C after 5 images (of 40; chunks of 32 without refinement): every finished SVG is
    on disk and complete, nothing else is, and the exit code is 130."""
    import im2vec_cli.api as api
    import im2vec_cli.cli.convert as convert

    d = tmp_path / "in"
    d.mkdir()
    for i in range(40):
        png(d / f"{i:02d}.png")
    monkeypatch.setattr(convert, "VECTORIZE_CHUNK", 5)
    real, done = api.vectorize, []

    def interrupted(images, *a, **kw):
        if len(done) >= 5:
            raise KeyboardInterrupt
        out = real(images, *a, **kw)
        done.extend(out if isinstance(out, list) else [out])
        return out

    monkeypatch.setattr(api, "vectorize", interrupted)
    res = CliRunner().invoke(cli, ["vectorize", str(d), "-o", str(tmp_path / "out"), refine, "--model", model_dir])
    assert res.exit_code == 130, res.output
    written = sorted((tmp_path / "out").iterdir())
    assert [p.name for p in written] == [f"{i:02d}.svg" for i in range(5)]
    for p in written:
        check_svg(p.read_text(), 40, 24)


def test_resource_bounds_under_a_memory_limit(tmp_path):
    """Endless stdin, a huge render and a huge SVG, as real processes limited to 4 GiB of
    address space: each is refused with one error line (before the fixes: 20 GB resident,
    the kernel's OOM killer, and minutes with no output)."""
    import resource

    (tmp_path / "t.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 64 64">'
                                    '<path d="M 1 1 L 60 1 L 30 60 Z"/></svg>')
    (tmp_path / "big.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 64 64"><path d="M 1 1 '
                                      + "L 2 2 L 1 1 " * 500_000 + 'Z"/></svg>')
    limit = 4 * 2**30
    cases = [(["vectorize", "-", "-o", str(tmp_path / "out.svg")], "/dev/zero", "more than 256 MiB"),
             (["render", str(tmp_path / "t.svg"), "--scale", "1000", "-o", str(tmp_path / "out.png")], None,
              "megapixels"),
             (["render", str(tmp_path / "big.svg"), "-o", str(tmp_path / "out.png")], None, "segments")]
    for args, stdin, message in cases:
        with open(stdin or os.devnull, "rb") as f:
            r = subprocess.run([sys.executable, "-m", "im2vec_cli", *args], stdin=f, capture_output=True, text=True,
                               timeout=300, preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (limit, limit)))
        assert r.returncode == 1, (args, r.stderr[-500:])
        assert r.stderr.count("Error:") == 1 and message in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert not list(tmp_path.glob("out*")) and not list(tmp_path.glob(".out*"))


def test_sample_streams_and_bounds_the_contact_sheet(tmp_path, model_dir, monkeypatch):
    import im2vec_cli.cli.generate as generate

    monkeypatch.setattr(generate, "DECODE_CHUNK", 7)
    monkeypatch.setattr(generate, "CONTACT_MAX", 10)
    res = CliRunner().invoke(cli, ["sample", "--n", "30", "-o", str(tmp_path / "s"), "--model", model_dir])
    assert res.exit_code == 0, res.output
    assert len(list((tmp_path / "s").glob("sample_*.svg"))) == 30
    with Image.open(tmp_path / "s" / "contact.png") as sheet:
        assert sheet.size == (8 * 96, 2 * 96)  # the first 10 samples: two rows of 8 cells
    whole = CliRunner().invoke(cli, ["sample", "--n", "30", "-o", str(tmp_path / "t"), "--model", model_dir])
    assert whole.exit_code == 0
    for p in (tmp_path / "s").glob("sample_*.svg"):  # chunking changes nothing
        assert p.read_bytes() == (tmp_path / "t" / p.name).read_bytes()
