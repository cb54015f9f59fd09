"""Clean outlines on three held-out sets against potrace and vtracer (issue "vectorize: clean,
complete outlines").

Sets, built here from packages that no shipped model trained on (the fonts model's glyphs
come from shared/data/font-packages.txt; the icons model from Material Design Icons, the emoji
model from Twemoji):

- **glyphs**: a-z, A-Z, 0-9 of ten faces of GNU FreeFont and Lato (Debian fonts-freefont-ttf,
  fonts-lato; neither package is in the fonts list), at 64 px like the Fonts dataset, with
  the true outline from fontTools;
- **icons**: Font Awesome Free 7.3.1 solid icons (npm @fortawesome/fontawesome-free), an even
  spread of 120, at 64 px;
- **emoji**: OpenMoji faces (npm @iconify-json/openmoji 1.2.29), an even spread of 120 of the
  names with "face", at 64 px.

Per tool and set, all on the same images in one run: IoU@4x of the ink (two-tone sets),
MSE@1x against the input, MSE@4x against the source SVG rendered at 4x, topology correct (the
4x render has as many pieces and holes, of at least an input pixel each, as the source's), images with cracks (background
showing at 4x where the source is ink, more than 0.75 input px inside its edge), paths and
cubic segments per image (lines count as segments), median ms per image, and the share of
valid SVGs (every subpath closed; for im2vec also: cubics only).

Run: ``make bench-outlines`` (installs the tools and sets first), or
``python bench/outlines.py --src DIR [--sets glyphs,icons,emoji] [--limit N] [--markdown F]``.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import re
import shlex
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import torch
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

from im2vec_cli import api  # noqa: E402
from im2vec_cli.data.fonts import find_fonts, render_png  # noqa: E402
from im2vec_cli.data.glyphs import glyph_image  # noqa: E402
from im2vec_cli.files import encode_png, load_image  # noqa: E402
from im2vec_cli.vector import rasterize_svg, to_svg  # noqa: E402
from vectorize import potrace, svg_structure  # noqa: E402

SIZE, UP = 64, 4
CHARS = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789"
FACES = [("FreeSans", "Regular"), ("FreeSans", "Bold"), ("FreeSans", "Oblique"), ("FreeSerif", "Regular"),
         ("FreeSerif", "Bold Italic"), ("FreeMono", "Bold"), ("Lato", "Regular"), ("Lato", "Black"),
         ("Lato", "Italic"), ("Lato", "Light")]
MODELS = {"glyphs": "fonts", "icons": "icons", "emoji": "emoji"}
TWO_TONE = {"glyphs", "icons"}
COMPACT_TOL = 1.0
DUMP = None  # --dump DIR: every tool's SVGs, to look at


# --- the sets ----------------------------------------------------------------------------------


def _used_packages() -> set[str]:
    return set((ROOT.parent / "shared" / "data" / "font-packages.txt").read_text().split())


def held_out_fonts(accept) -> list[tuple[tuple[str, str], object]]:
    """The installed fonts whose ``(family, style)`` ``accept`` takes, each face once, as
    ``(face, TTFont)``; stops if one comes from a package the fonts training set uses."""
    from fontTools.ttLib import TTFont

    from im2vec_cli.data.fonts import _names

    used, out, seen = _used_packages(), [], set()
    for path in find_fonts():
        try:
            font = TTFont(str(path), fontNumber=0, lazy=True)
            face = _names(font)
        except Exception:  # noqa: BLE001 - unreadable fonts are not part of the set
            continue
        if not accept(face) or face in seen:
            continue
        seen.add(face)
        owner = subprocess.run(["dpkg", "-S", str(path)], capture_output=True, text=True).stdout.split(":")[0]
        if owner in used:
            raise SystemExit(f"{face} comes from {owner}, which the fonts training set uses")
        out.append((face, font))
    return out


def glyphs(limit: int | None) -> list[dict]:
    out = []
    for face, font in held_out_fonts(lambda face: face in FACES):
        for c in CHARS:
            svg = to_svg(glyph_image(font, c, size=SIZE, margin=4.0), decimals=3)
            out.append({"name": f"{face[0]}-{face[1]}-{ord(c):04x}", "svg": svg})
    out.sort(key=lambda g: g["name"])
    return _spread(out, limit)


def icons(src: Path, limit: int | None) -> list[dict]:
    files = sorted((src / "fa" / "package" / "svgs" / "solid").glob("*.svg"))
    return _spread([{"name": f.stem, "svg": f.read_text()} for f in files], limit or 120)


def emoji(src: Path, limit: int | None) -> list[dict]:
    data = json.loads((src / "om" / "package" / "icons.json").read_text())
    w, h = data.get("width", 72), data.get("height", 72)
    names = sorted(n for n in data["icons"] if "face" in n)
    rows = [{"name": n, "svg": f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w} {h}">'
             f'{data["icons"][n]["body"]}</svg>'} for n in names]
    return _spread(rows, limit or 120)


def _spread(rows: list[dict], n: int | None) -> list[dict]:
    if not n or n >= len(rows):
        return rows
    return [rows[round(i * (len(rows) - 1) / (n - 1))] for i in range(n)] if n > 1 else rows[:1]


def _with_png(rows: list[dict], gray: bool) -> list[dict]:
    """The input PNGs: glyphs as the Fonts dataset renders them (grey), icons and emoji in colour
    as ``im2vec data svg`` does, all over white."""
    for r in rows:
        r["png"] = render_png(r["svg"], SIZE) if gray else encode_png(
            Image.fromarray(np.round(rasterize_svg(r["svg"], SIZE, SIZE) * 255).astype(np.uint8)))
        r["truth"] = rasterize_svg(r["svg"], SIZE * UP, SIZE * UP)  # (4H, 4W, 3)
    return rows


# --- scoring ------------------------------------------------------------------------------------


def _ink(rgb: np.ndarray) -> np.ndarray:
    return rgb.mean(-1) < 0.5


SPECK = UP * UP  # px at 4x: pieces and holes smaller than one input pixel are not counted


def _topology(mask: np.ndarray) -> tuple[int, int]:
    """Pieces (8-connected ink) and holes (4-connected background not touching the border), each
    of at least one input pixel (``SPECK``): the source renders of some FreeFont glyphs, whose
    contours overlap, hold sub-pixel pin holes where their contours meet, which no tool keeps."""
    from scipy.ndimage import label

    ink, pieces = label(mask, structure=np.ones((3, 3)))
    bg, n = label(~mask)
    border = set(np.unique(np.concatenate([bg[0], bg[-1], bg[:, 0], bg[:, -1]]))) - {0}
    big_ink = int((np.bincount(ink.ravel())[1:] >= SPECK).sum())
    sizes = np.bincount(bg.ravel())
    holes = sum(1 for i in range(1, n + 1) if i not in border and sizes[i] >= SPECK)
    return big_ink, holes


CRACK_DEPTH = 1.5  # input px: background this deep inside the source's ink is a crack, not an edge placement


def _cracks(truth: np.ndarray, out: np.ndarray) -> bool:
    """Background (near white) showing where the source is ink, at least ``CRACK_DEPTH`` input px
    inside its edge (rounded corners and edges a pixel off are not cracks; seams and holes are)."""
    from scipy.ndimage import distance_transform_edt

    ink = (1 - truth).max(-1) > 0.1
    inner = distance_transform_edt(np.pad(ink, 1))[1:-1, 1:-1] > CRACK_DEPTH * UP  # the canvas edge is an edge
    return bool((inner & (out.min(-1) > 0.9)).any())


def score(rows: list[dict], outputs: list[str], times: list[float], two_tone: bool, cubic_only: bool) -> dict:
    ious, mse1, mse4, topo, crack, paths, segs, valid = [], [], [], [], [], [], [], 0
    for r, svg in zip(rows, outputs):
        big = rasterize_svg(svg, SIZE * UP, SIZE * UP)
        small = rasterize_svg(svg, SIZE, SIZE)
        target = np.asarray(Image.open(io.BytesIO(r["png"])).convert("RGB"), dtype=np.float64) / 255
        mse1.append(float(((small - target) ** 2).mean()))
        mse4.append(float(((big - r["truth"]) ** 2).mean()))
        crack.append(_cracks(r["truth"], big))
        if two_tone:
            t, o = _ink(r["truth"]), _ink(big)
            ious.append(float((t & o).sum() / max((t | o).sum(), 1)))
            topo.append(_topology(t) == _topology(o))
        n, closed = svg_structure(svg)
        ok = closed and (not cubic_only or not re.search(r'\sd="[^"]*[LlHhVvQqTtAaSs]', svg))
        valid += int(ok)
        segs.append(n)
        paths.append(svg.count("<path"))
    row = {"mse1": np.mean(mse1), "mse4": np.mean(mse4), "cracks": np.mean(crack), "paths": np.mean(paths),
           "segments": np.mean(segs), "valid": valid / len(rows), "ms": 1e3 * statistics.median(times)}
    if two_tone:
        row.update(iou=np.mean(ious), topology=np.mean(topo))
    return row


# --- the tools ------------------------------------------------------------------------------------


def vtracer(png: bytes, mode: str) -> str:
    import vtracer as vt

    return vt.convert_raw_image_to_svg(png, img_format="png", colormode=mode)


def tools(model, two_tone: bool) -> dict:
    def im2vec(**kw):
        return lambda r: api.vectorize(load_image(r["name"] + ".png", r["png"]), model, **kw).to_svg()

    out = {
        "im2vec (default)": im2vec(),
        f"im2vec (--tolerance {COMPACT_TOL:g})": im2vec(tolerance=COMPACT_TOL),
        "im2vec (--parts model)": im2vec(parts="model"),
        "im2vec (--no-refine)": im2vec(refine=False),
        "im2vec (--no-refine --parts model)": im2vec(refine=False, parts="model"),
    }
    if two_tone:
        out["potrace"] = lambda r: potrace(r["png"])
        out["vtracer (binary)"] = lambda r: vtracer(r["png"], "binary")
    out["vtracer (color)"] = lambda r: vtracer(r["png"], "color")
    return out


def run(name: str, rows: list[dict], only: set[str] | None) -> dict:
    model = api.load_model(MODELS[name], "cpu")
    two = name in TWO_TONE
    api.vectorize(load_image("w.png", rows[0]["png"]), model)  # warm-up
    results = {}
    for tool, fn in tools(model, two).items():
        if only and not any(o in tool for o in only):
            continue
        outs, times = [], []
        for r in rows:
            t = time.perf_counter()
            outs.append(fn(r))
            times.append(time.perf_counter() - t)
        results[tool] = score(rows, outs, times, two, tool.startswith("im2vec"))
        if DUMP:
            d = Path(DUMP, name, re.sub(r"[^a-z0-9]+", "_", tool.lower()).strip("_"))
            d.mkdir(parents=True, exist_ok=True)
            for r, svg in zip(rows, outs):
                (d / f"{r['name']}.svg").write_text(svg)
        print(f"{name:6s} {_line(tool, results[tool])}", flush=True)
    return results


def _line(tool: str, r: dict) -> str:
    parts = [f"{tool:26s}"]
    if "iou" in r:
        parts.append(f"IoU@4x {r['iou']:.4f}  topology {r['topology']:.1%}")
    parts.append(f"MSE@1x {r['mse1']:.5f}  MSE@4x {r['mse4']:.5f}  cracks {r['cracks']:.1%}  paths {r['paths']:.1f}  "
                 f"segments {r['segments']:.1f}  {r['ms']:.0f} ms  valid {r['valid']:.0%}")
    return "  ".join(parts)


def markdown(all_rows: dict, sizes: dict, command: str = "make bench-outlines") -> str:
    lines = [f"# Clean outlines on held-out sets\n\nWritten by `{command}` "
             f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} CPU cores, torch "
             f"{torch.__version__}, {torch.get_num_threads()} threads). All tools on the same images in one run; "
             "the sets and metrics are described in bench/outlines.py.\n"]
    for name, rows in all_rows.items():
        lines += [f"\n## {name}: {sizes[name]} images at {SIZE} px (model `{MODELS[name]}`)\n",
                  "| tool | IoU@4x | topology correct | images with cracks | MSE@1x | MSE@4x | paths | segments | ms / image | valid |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for tool, r in rows.items():
            iou = f"{r['iou']:.4f}" if "iou" in r else "–"
            topo = f"{r['topology']:.1%}" if "topology" in r else "–"
            lines.append(f"| {tool} | {iou} | {topo} | {r['cracks']:.1%} | {r['mse1']:.5f} | {r['mse4']:.5f} | "
                         f"{r['paths']:.1f} | {r['segments']:.1f} | {r['ms']:.0f} | {r['valid']:.0%} |")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--src", default="bench/.sets", help="folder holding fa/ (Font Awesome) and om/ (OpenMoji)")
    ap.add_argument("--sets", default="glyphs,icons,emoji")
    ap.add_argument("--limit", type=int, default=None, help="images per set (even spread)")
    ap.add_argument("--tools", default=None, help="comma-separated substrings of tool names to run (default: all)")
    ap.add_argument("--markdown", default=None)
    ap.add_argument("--dump", default=None, help="write every output SVG under this folder")
    args = ap.parse_args()
    global DUMP
    DUMP = args.dump
    torch.set_num_threads(max(1, torch.get_num_threads()))
    src = Path(args.src)
    builders = {"glyphs": lambda: glyphs(args.limit), "icons": lambda: icons(src, args.limit),
                "emoji": lambda: emoji(src, args.limit)}
    only = set(args.tools.split(",")) if args.tools else None
    results, sizes = {}, {}
    for name in args.sets.split(","):
        rows = _with_png(builders[name](), gray=name == "glyphs")
        sizes[name] = len(rows)
        print(f"{name}: {len(rows)} images", flush=True)
        results[name] = run(name, rows, only)
    command = "make bench-outlines" if not (args.tools or args.limit or args.sets != ap.get_default("sets")) else (
        "python bench/outlines.py " + " ".join(shlex.quote(a) for a in sys.argv[1:]))
    table = markdown(results, sizes, command)
    print(table)
    if args.markdown:
        Path(args.markdown).write_text(table)


if __name__ == "__main__":
    main()
