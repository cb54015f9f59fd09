"""Bad input for `vectorize`: broken, odd and huge images, stdin, bad option values and output
paths. Each builder ``in_x(d, model_dir)`` writes its files into ``d`` and returns the command's
arguments and its stdin bytes (or None)."""

from __future__ import annotations

import io
import os
import zlib
from pathlib import Path

import numpy as np
from PIL import Image

from tests.cli.bad_input import chunk, glyph_like, png_bytes, save
from tests.helpers import png


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
    (d / "x.png").write_bytes(png_bytes(40, 40, b"\xff" * 5)[:33] + chunk(b"IDAT", b"\x78\x9c" + os.urandom(40))
                              + chunk(b"IEND", b""))
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_one_pixel(d, m):
    save(Image.new("L", (1, 1), 0), d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_sliver(d, m):
    save(Image.new("L", (2, 500), 0), d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_20000_square(d, m):
    (d / "x.png").write_bytes(png_bytes(20000, 20000, b"\xff" * 2500))  # a real, complete 1-bit image
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_beyond_max_memory(d, m):
    # 6000 x 6000 (36 MP) needs about 1.1 GB to read; an 800 MiB budget holds 18.9 MP
    (d / "x.png").write_bytes(png_bytes(6000, 6000, b"\xff" * 750))
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg"), "--max-memory", "800M"], None


def in_max_memory_too_small(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--max-memory", "100M"], None


def in_decompression_bomb(d, m):
    # a header claiming 100000 x 100000 pixels in front of a few bytes of data
    ihdr = (100000).to_bytes(4, "big") * 2 + bytes([8, 0, 0, 0, 0])
    (d / "x.png").write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 99))
                              + chunk(b"IEND", b""))
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
    glyph_like().convert("RGB").save(buf, format="JPEG")
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
    arr = (np.asarray(glyph_like(), np.uint16) * 257).astype(np.uint16)
    img = Image.fromarray(arr)
    assert img.mode == "I;16"
    save(img, d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_palette_transparency(d, m):
    img = glyph_like().convert("P")
    img.info["transparency"] = 255  # white (index 255 in the grey palette) is transparent
    save(img, d / "x.png", transparency=255)
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_cmyk_jpg(d, m):
    save(glyph_like().convert("CMYK"), d / "x.jpg", format="JPEG")
    return ["vectorize", str(d / "x.jpg"), "-o", str(d / "out.svg")], None


def in_animated_gif(d, m):
    frames = [glyph_like(), glyph_like().transpose(Image.Transpose.ROTATE_90)]
    frames[0].save(d / "x.gif", save_all=True, append_images=frames[1:], duration=100, loop=0)
    return ["vectorize", str(d / "x.gif"), "-o", str(d / "out.svg")], None


def in_animated_png(d, m):
    frames = [glyph_like().convert("RGB"), Image.new("RGB", (48, 48), "black")]
    frames[0].save(d / "x.png", save_all=True, append_images=frames[1:], duration=100)
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_exif_rotated_jpg(d, m):
    img = Image.new("RGB", (60, 30), "white")
    exif = Image.Exif()
    exif[0x0112] = 6  # orientation: rotate 90 degrees to display -> 30 x 60
    img.save(d / "x.jpg", exif=exif)
    return ["vectorize", str(d / "x.jpg"), "-o", str(d / "out.svg")], None


def in_all_white(d, m):
    save(Image.new("RGB", (50, 40), "white"), d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_fully_transparent(d, m):
    save(Image.new("RGBA", (50, 40), (10, 20, 30, 0)), d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_all_black(d, m):
    save(Image.new("L", (50, 40), 0), d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_stdin_empty(d, m):
    return ["vectorize", "-", "-o", str(d / "out.svg")], b""


def in_stdin_junk(d, m):
    return ["vectorize", "-", "-o", str(d / "out.svg")], b"GIF89a" + b"\0" * 20


def in_output_parent_missing(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "no" / "such" / "dir" / "out.svg")], None


def in_unknown_option(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--frobnicate"], None


def in_segments_zero(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--segments", "0"], None


def in_folder_to_stdout(d, m):
    (d / "in").mkdir()
    png(d / "in" / "a.png")
    return ["vectorize", str(d / "in"), "-o", "-"], None


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


def in_stdin_endless(d, m):
    from im2vec_cli import files

    return ["vectorize", "-", "-o", str(d / "out.svg")], b"\0" * (files.MAX_INPUT_BYTES + 1)


in_preset_unknown = vectorize_with("--preset", "poster")


in_speckle_negative = vectorize_with("--filter-speckle", "-1")


in_grow_negative = vectorize_with("--grow", "-1")


in_grow_huge = vectorize_with("--grow", "100000")


in_speckle_huge = vectorize_with("--filter-speckle", "100000")


in_speckle_not_a_number = vectorize_with("--filter-speckle", "2px")


in_effort_unknown = vectorize_with("--effort", "sketch")


def in_preset_pixel_on_a_photo(d, m):
    """Pixel art forced on a picture of more colours than pixel art has: traced as it is."""
    rng = np.random.default_rng(0)
    Image.fromarray(rng.integers(0, 256, (48, 48, 3), dtype=np.uint8)).save(d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg"), "--preset", "pixel"], None


def in_preset_scan_on_white(d, m):
    save(Image.new("RGB", (64, 64), (255, 255, 255)), d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg"), "--preset", "scan"], None


def in_near_black_16bit(d, m):
    """16-bit samples all under 256 (a near-black picture): scaled by 65535, not read as 8-bit."""
    arr = np.asarray(glyph_like(), np.uint16) // 2  # 0 and 127 of 65535
    save(Image.fromarray(arr.astype(np.uint16)), d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_corrupt_exif(d, m):
    """An EXIF block whose tag points past its end: Pillow's warnings stay off stderr."""
    exif = b"Exif\x00\x00MM\x00\x2a\x00\x00\x00\x08\x00\x05\x01\x12\x00\x03\xff\xff\xff\xff" + b"\xff" * 10
    save(glyph_like().convert("RGB"), d / "x.png", exif=exif)
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_output_slash_onto_a_file(d, m):
    """``-o existing.svg/``: a slash names a folder; the file there is not replaced."""
    save(glyph_like(), d / "x.png")
    (d / "existing.svg").write_text("someone's work")
    return ["vectorize", str(d / "x.png"), "-o", f"{d / 'existing.svg'}/"], None


def in_hard_edged_clip_art(d, m):
    """Flat circles drawn without anti-aliasing at 384 px: a drawing of curves, not pixel art
    (traced along its pixels it took 80 s and 75,196 segments)."""
    from PIL import ImageDraw

    rng = np.random.default_rng(1)
    img = Image.new("RGB", (384, 384), "white")
    draw = ImageDraw.Draw(img)
    colors = [tuple(int(c) for c in rng.integers(0, 256, 3)) for _ in range(10)]
    for i in range(120):
        x, y, r = *rng.uniform(0, 384, 2), rng.uniform(3, 48)
        draw.ellipse((x - r, y - r, x + r, y + r), fill=colors[i % 10])
    save(img, d / "x.png")
    return ["vectorize", str(d / "x.png"), "-o", str(d / "out.svg")], None


def in_max_memory_not_finite(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--max-memory", "1e400"], None
