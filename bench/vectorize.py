"""Vectorize fidelity against the tools people use (issue "Vectorize fidelity").

Test set: the glyphs a-z, A-Z, 0-9 at 64 px of font families that are *not* in the fonts
training split (default: Liberation Sans Narrow, 4 styles, 248 glyphs, from the Debian
package fonts-liberation), rendered exactly like the Fonts dataset, with the true outline
from fontTools.

Tools, on the same images in one run: im2vec amortised (the model's own paths, `--no-refine --parts
model`, and its guess drawn clean, `--no-refine`), im2vec refined (`--effort fast`, the
default, and `--effort best`), potrace (defaults),
potrace on a 4x bilinear upsample, vtracer (binary mode), and the trivial baseline (bilinear
4x upsample thresholded at 0.5).

Per tool: IoU at 4x against the true outline rendered at 4x (both thresholded at 0.5), MSE at
1x against the input, cubic segments per glyph (lines count as segments), SVG bytes, median
ms per glyph, and the fraction of valid outputs (SVG whose every subpath is closed).
Then the throughput on a folder of 1000 glyphs in one command: `im2vec vectorize DIR --no-refine` against
`potrace DIR/*.pgm`, both as a user runs them (process start and model load included).

Run: ``make bench-vectorize`` (installs potrace, fonts-liberation and vtracer first), or
``python bench/vectorize.py [--limit N] [--skip-refined] [--markdown docs/VECTORIZE.md]``.
"""

from __future__ import annotations

import argparse
import io
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from im2vec_cli.data.fonts import DEFAULT_CHARS, _names, find_fonts, render_png, split_of  # noqa: E402
from im2vec_cli.data.glyphs import glyph_image  # noqa: E402
from im2vec_cli.evaluate import outline_iou, svg_mask  # noqa: E402
from im2vec_cli.files import load_image  # noqa: E402
from im2vec_cli.infer import vectorize  # noqa: E402
from im2vec_cli.model.pretrained import from_pretrained  # noqa: E402
from im2vec_cli.options import Plan, effort_plan  # noqa: E402
from im2vec_cli.raster import set_compile  # noqa: E402
from im2vec_cli.refine import refine  # noqa: E402
from im2vec_cli.vector import rasterize_svg, to_svg  # noqa: E402

SIZE, UP = 64, 4
COMPACT = {"quality": 2e-3, "simplify": 1.0}  # the compact preset, as CLI options below
FAST_NAME = "im2vec refined, fast"  # `vectorize --effort fast`, the CLI's default for one image
COMPACT_NAME = "im2vec refined, compact"  # --effort best --segments auto --quality 2e-3 --simplify 1
ANCHORS = {  # the issue's figures, same kind of machine, 248 DejaVu/Liberation glyphs at 64 px
    "potrace": (0.932, 12.6, 5.3),
    "potrace 4x upsample": (0.9716, 41.7, None),
    "vtracer (binary)": (0.889, 25.2, None),
    "bilinear 4x threshold": (0.9735, None, None),
}


def glyph_set(families: list[str], chars: str = DEFAULT_CHARS) -> list[dict]:
    """Glyph PNG bytes and true-outline SVGs of every installed style of ``families``."""
    from fontTools.ttLib import TTFont

    out, seen = [], set()
    for path in find_fonts():
        try:
            font = TTFont(str(path), fontNumber=0, lazy=True)
            fam, style = _names(font)
        except Exception:  # noqa: BLE001 - unreadable fonts are not part of the set
            continue
        if fam not in families or (fam, style) in seen:
            continue
        if split_of(fam) == "train":
            raise SystemExit(f"{fam} is in the fonts training split; pick a held-out family")
        seen.add((fam, style))
        for c in chars:
            svg = to_svg(glyph_image(font, c, size=SIZE, margin=4.0), decimals=3)
            out.append({"name": f"{fam}-{style}-{ord(c):04x}", "svg": svg, "png": render_png(svg, SIZE)})
    return out


# --- SVG structure (any tool's output) -------------------------------------------------------

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_ARGS = {"m": 2, "l": 2, "h": 1, "v": 1, "c": 6, "s": 4, "q": 4, "t": 2, "a": 7}


def svg_structure(text: str) -> tuple[int, bool]:
    """Drawn segments (curves and lines) over all ``<path>``s, and whether every subpath is closed."""
    segs, closed = 0, True
    for d in re.findall(r'\sd="([^"]*)"', text):
        open_sub = False
        for cmd, args in re.findall(r"([MmLlHhVvCcSsQqTtAaZz])([^MmLlHhVvCcSsQqTtAaZz]*)", d):
            c = cmd.lower()
            if c == "z":
                open_sub = False
                continue
            n = len(re.findall(_NUM, args)) // _ARGS[c]
            if c == "m":
                if open_sub:
                    closed = False
                open_sub = True
                segs += n - 1  # extra pairs after a moveto are linetos
            else:
                segs += n
        closed = closed and not open_sub
    return segs, closed


# --- the tools: each maps a glyph PNG to SVG text --------------------------------------------

def _pgm(img: Image.Image) -> bytes:
    buf = io.BytesIO()
    img.convert("L").save(buf, format="PPM")  # mode L -> binary PGM
    return buf.getvalue()


def potrace(png: bytes, up: int = 1) -> str:
    img = Image.open(io.BytesIO(png)).convert("L")
    if up > 1:
        img = img.resize((img.width * up, img.height * up), Image.BILINEAR)
    res = subprocess.run(["potrace", "-s", "-o", "-", "-"], input=_pgm(img), capture_output=True, check=True)
    return res.stdout.decode()


def vtracer_svg(png: bytes) -> str:
    import vtracer

    return vtracer.convert_raw_image_to_svg(png, img_format="png", colormode="binary")


def bilinear_mask(png: bytes) -> np.ndarray:
    img = Image.open(io.BytesIO(png)).convert("L")
    big = np.asarray(img.resize((img.width * UP, img.height * UP), Image.BILINEAR), dtype=np.float64) / 255
    return big < 0.5


# --- scoring ----------------------------------------------------------------------------------

def score(glyphs: list[dict], outputs: list[str | np.ndarray], times: list[float]) -> dict:
    ious, mses, segs, sizes, valid = [], [], [], [], 0
    for g, out in zip(glyphs, outputs):
        truth = svg_mask(g["svg"], SIZE * UP)
        target = np.asarray(Image.open(io.BytesIO(g["png"])).convert("L"), dtype=np.float64) / 255
        if isinstance(out, np.ndarray):  # a raster baseline: no SVG
            ious.append(outline_iou(out, truth))
            small = out.reshape(SIZE, UP, SIZE, UP).mean((1, 3))
            mses.append(float(((1 - small - target) ** 2).mean()))
            continue
        n, closed = svg_structure(out)
        valid += int(closed)
        segs.append(n)
        sizes.append(len(out.encode()))
        ious.append(outline_iou(svg_mask(out, SIZE * UP), truth))
        mses.append(float(((rasterize_svg(out, SIZE, SIZE).mean(-1) - target) ** 2).mean()))
    row = {"iou": float(np.mean(ious)), "mse": float(np.mean(mses))}
    if segs:
        row.update(segments=float(np.mean(segs)), bytes=float(np.mean(sizes)), valid=valid / len(outputs))
    if times:
        row["ms"] = 1e3 * statistics.median(times)
    return row


def run_tool(fn, glyphs: list[dict]) -> tuple[list, list[float]]:
    outs, times = [], []
    for g in glyphs:
        t = time.perf_counter()
        outs.append(fn(g))
        times.append(time.perf_counter() - t)
    return outs, times


def throughput(glyphs: list[dict], n: int, model: str) -> dict:
    """Wall seconds for ``n`` glyphs in one command each: im2vec vectorize DIR --no-refine (the model
    alone; bench/folder.py measures the refined default) vs potrace *.pgm."""
    with tempfile.TemporaryDirectory() as tmp:
        src, pgm, out = Path(tmp, "png"), Path(tmp, "pgm"), Path(tmp, "svg")
        for d in (src, pgm, out):
            d.mkdir()
        for i in range(n):
            g = glyphs[i % len(glyphs)]
            (src / f"{i:04d}.png").write_bytes(g["png"])
            (pgm / f"{i:04d}.pgm").write_bytes(_pgm(Image.open(io.BytesIO(g["png"]))))
        exe = [sys.executable, "-m", "im2vec_cli", "vectorize", str(src), "-o", str(out), "--model", model, "--no-refine"]
        t = time.perf_counter()
        subprocess.run(exe, check=True, capture_output=True)
        ours = time.perf_counter() - t
        assert len(list(out.glob("*.svg"))) == n
        t = time.perf_counter()
        subprocess.run(["potrace", "-s", *sorted(str(p) for p in pgm.glob("*.pgm"))], check=True, capture_output=True)
        theirs = time.perf_counter() - t
        assert len(list(pgm.glob("*.svg"))) == n
    return {"glyphs": n, "im2vec_s": ours, "potrace_s": theirs}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--families", default="Liberation Sans Narrow", help="comma-separated held-out font families")
    ap.add_argument("--model", default="fonts")
    ap.add_argument("--limit", type=int, default=None, help="first N glyphs only (quick runs)")
    ap.add_argument("--skip-refined", action="store_true")
    ap.add_argument("--segments", default=None, help="im2vec --segments for both modes (a number or 'auto')")
    ap.add_argument("--quality", type=float, default=None, help="im2vec --quality with --segments auto")
    ap.add_argument("--throughput", type=int, default=1000, help="glyphs in the one-command throughput test (0: skip)")
    ap.add_argument("--markdown", default=None, help="also write the table to this file")
    args = ap.parse_args()
    torch.set_num_threads(max(1, torch.get_num_threads()))
    glyphs = glyph_set([f.strip() for f in args.families.split(",")])
    if not glyphs:
        raise SystemExit(f"no installed fonts of {args.families!r} (apt-get install fonts-liberation)")
    glyphs = glyphs[: args.limit] if args.limit else glyphs
    print(f"{len(glyphs)} glyphs of {args.families} at {SIZE} px (held out of the training split)")

    set_compile(False)
    model = from_pretrained(args.model)
    tools = _tools(model, glyphs, args)
    tools["im2vec amortised"](glyphs[0])  # warm-up (lazy init)
    rows = {}
    for name, fn in tools.items():
        if fn is None:
            continue
        outs, times = run_tool(fn, glyphs)
        rows[name] = score(glyphs, outs, times)
        print(_line(name, rows[name]), flush=True)
    print()
    table = markdown(rows, len(glyphs), args)
    print(table)
    if args.throughput:
        t = throughput(glyphs, args.throughput, args.model)
        verdict = "met" if t["potrace_s"] >= t["im2vec_s"] else "not met"
        line = (f"\n{t['glyphs']} glyphs in one command: im2vec vectorize {t['im2vec_s']:.2f} s "
                f"({t['glyphs'] / t['im2vec_s']:.0f} glyphs/s, process start and model load included), "
                f"potrace {t['potrace_s']:.2f} s ({t['glyphs'] / t['potrace_s']:.0f} glyphs/s); "
                f"ratio {t['potrace_s'] / t['im2vec_s']:.2f}x potrace's speed (target >= 1x: {verdict})")
        print(line)
        table += line + "\n"
    if args.markdown:
        Path(args.markdown).write_text(table)


def _tools(model, glyphs, args) -> dict:
    """Tool name -> ``glyph -> SVG text`` (``None``: skipped in this run)."""
    images = {g["name"]: load_image(g["name"] + ".png", g["png"]) for g in glyphs}
    opts = _segment_options(model, args)

    def amortised(g):
        return to_svg(vectorize(model, [images[g["name"]]], **opts)[0])

    def amortised_clean(g):
        return to_svg(vectorize(model, [images[g["name"]]], clean=True, **opts)[0])

    def refined(g):  # the model's own parts: bench/outlines.py measures the clean outlines (the default)
        return to_svg(refine(model, images[g["name"]], effort_plan("best", parts="model", **opts))[0])

    def refined_fast(g):
        return to_svg(refine(model, images[g["name"]], effort_plan("fast", parts="model", **opts))[0])

    compact = Plan(simplify_tol=COMPACT["simplify"], parts="model", segments="auto", quality=COMPACT["quality"])

    def refined_compact(g):
        return to_svg(refine(model, images[g["name"]], compact)[0])

    tools = {
        "im2vec amortised": amortised,
        "im2vec amortised, clean": amortised_clean,
        FAST_NAME: None if args.skip_refined else refined_fast,
        "im2vec refined": None if args.skip_refined else refined,
        COMPACT_NAME: None if args.skip_refined or opts or model.segment_predictor is None else refined_compact,
        "potrace": lambda g: potrace(g["png"]),
        "potrace 4x upsample": lambda g: potrace(g["png"], UP),
        "vtracer (binary)": lambda g: vtracer_svg(g["png"]),
        "bilinear 4x threshold": lambda g: bilinear_mask(g["png"]),
    }
    return tools


def _segment_options(model, args) -> dict:
    if args.segments == "auto":
        return {"segments": "auto", "quality": args.quality}
    return {"segments": int(args.segments)} if args.segments else {}


def _line(name: str, r: dict) -> str:
    parts = [f"{name:24s} IoU@4x {r['iou']:.4f}", f"MSE {r['mse']:.5f}"]
    if "segments" in r:
        parts += [f"segments {r['segments']:.1f}", f"bytes {r['bytes']:.0f}", f"valid {r['valid']:.3f}"]
    if "ms" in r:
        parts.append(f"{r['ms']:.1f} ms/glyph")
    return "  ".join(parts)


def markdown(rows: dict, n: int, args) -> str:
    def f(v, fmt):
        return "" if v is None else format(v, fmt)

    lines = [
        "| tool | IoU@4x | MSE@1x | cubic segments / glyph | SVG bytes | ms / glyph (median) | valid | issue's anchor IoU / segments / ms |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, r in rows.items():
        a = ANCHORS.get(name)
        anchor = "" if a is None else " / ".join("–" if v is None else f"{v:g}" for v in a)
        lines.append(f"| {name} | {r['iou']:.4f} | {r['mse']:.5f} | {f(r.get('segments'), '.1f')} | "
                     f"{f(r.get('bytes'), '.0f')} | {f(r.get('ms'), '.1f')} | {f(r.get('valid'), '.3f')} | {anchor} |")
    for name in (FAST_NAME, "im2vec refined", COMPACT_NAME):
        r = rows.get(name)
        if r:
            ok = r["iou"] >= 0.98 and r["segments"] <= 13 and r["ms"] <= 1000
            lines.append(f"\nTarget for {name} (IoU@4x >= 0.980 with <= 13 segments, <= 1 s per glyph): "
                         f"IoU {r['iou']:.4f}, {r['segments']:.1f} segments, {r['ms'] / 1e3:.2f} s: "
                         f"{'met' if ok else 'not met'}.")
    opts = f" --segments {args.segments}" if args.segments else ""
    opts += f" --quality {args.quality}" if args.quality else ""
    note = (f"\n\n*{COMPACT_NAME}*: `im2vec vectorize IMG --effort best --segments auto --quality {COMPACT['quality']:g} "
            f"--simplify {COMPACT['simplify']:g}`; *{FAST_NAME}*: `im2vec vectorize IMG` (the default for one image, "
            f"`--effort fast`); *im2vec refined*: `im2vec vectorize IMG --effort best`; *im2vec amortised*: "
            f"`im2vec vectorize IMG --no-refine --parts model`; *im2vec amortised, clean*: `im2vec vectorize IMG --no-refine`.")
    head = (f"# Vectorize fidelity against potrace and vtracer\n\nWritten by `make bench-vectorize` "
            f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} CPU cores, torch "
            f"{torch.__version__}). All tools on the same images in one run; see bench/vectorize.py for the "
            f"metrics.\n\n{n} glyphs ({args.families}, held out of training) at {SIZE} px; model `{args.model}`{opts}; "
            f"{torch.get_num_threads()} threads; `python bench/vectorize.py{opts}`\n\n")
    return head + "\n".join(lines) + note + "\n"


if __name__ == "__main__":
    if shutil.which("potrace") is None:
        raise SystemExit("potrace is not installed (apt-get install potrace; `make bench-vectorize` does it)")
    main()
