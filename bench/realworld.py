"""The pictures people bring (issue "vectorize the pictures people bring"): im2vec against potrace
and vtracer on scans, logos, pixel art, line art, photos and a large scanned page, all on the
same pictures in one run, scored against the clean pictures the inputs were made from.

Sets, built here from packages no shipped model trained on (the fonts model's glyphs come from
shared/data/font-packages.txt, the icons model's from Material Design Icons, the emoji model's
from Twemoji):

- **scans**: glyphs of GNU FreeFont and Lato (Debian fonts-freefont-ttf, fonts-lato) and Font
  Awesome Free 7.3.1 solid icons (npm), single glyphs, words and icons at 400-600 px and two
  icons at 1024 px, as a phone photo or scan makes them: tinted paper, uneven light, blur,
  noise, JPEG quality 40;
- **logos**: OpenMoji 1.2.29 symbols (npm @iconify-json/openmoji) at 512 px and two at 1024 px,
  half as JPEG q70;
- **pixel**: OpenMoji pictures drawn as 16-32 px sprites of at most 12 colours, upscaled 8x;
- **line**: Font Awesome icons drawn as 1-2 px strokes, and stroked circles and curves, at 512 px;
- **photos**: scikit-image's sample photos (astronaut, coffee, chelsea), posterised;
- **large**: a 2048 x 2048 scanned page of text (FreeSerif), degraded as the scans.

Per tool and set: MSE at 1x against the clean picture (photos: against the input), the share of
pictures whose topology (pieces and holes of the ink, each at least 4 px^2) is the clean
picture's (two-tone sets), paths and segments per picture, the median time per picture (im2vec:
the whole command, process start included) and the peak memory (im2vec's process). Contact
sheets (a crop of each picture at 4x: input, clean, im2vec, potrace, vtracer) go beside the table.

Run: ``make bench-realworld`` (installs the tools and sets first), or
``python bench/realworld.py --src bench/.sets [--sets scans,line] [--limit N] [--markdown F]``.
"""

from __future__ import annotations

import argparse
import io
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageFilter

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

from im2vec_cli.vector import rasterize_svg  # noqa: E402
from outlines import _topology, held_out_fonts  # noqa: E402
from vectorize import potrace, svg_structure  # noqa: E402

UP = 4  # contact sheets: crops at 4x
SMALL_SIDE = 600  # the time target is per picture of at most this many px a side (the 400-600 px ones)
SETS = ("scans", "logos", "pixel", "line", "photos", "large")
TWO_TONE = {"scans", "line", "large"}
LOGOS = ["linkedin", "openfoodfact", "recycling-symbol", "no-entry", "radioactive", "peace-symbol", "yin-yang",
         "stop-sign"]
LARGE_LOGOS = ["rainbow", "1st-place-medal"]
SPRITES = ["black-cat", "duck", "moai", "latte-macchiato", "red-heart", "rocket", "cherries", "strawberry"]
WORDS = ["Hamburg", "vector 42", "fox jumps"]


# --- the sets -----------------------------------------------------------------------------------


def _png(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.round(np.clip(arr, 0, 1) * 255).astype(np.uint8)).save(buf, "PNG")
    return buf.getvalue()


def _jpeg(arr: np.ndarray, quality: int) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.round(np.clip(arr, 0, 1) * 255).astype(np.uint8)).save(buf, "JPEG", quality=quality)
    return buf.getvalue()


def text_svg(font, text: str, height: int, margin: float = 0.12) -> tuple[str, int]:
    """``(svg, width)``: ``text`` in ``font`` (fontTools) on a canvas ``height`` px high, black."""
    from fontTools.pens.svgPathPen import SVGPathPen
    from fontTools.pens.transformPen import TransformPen

    gs, cmap, hmtx = font.getGlyphSet(), font.getBestCmap(), font["hmtx"]
    upm = font["head"].unitsPerEm
    asc, desc = font["hhea"].ascent, font["hhea"].descent
    scale = height * (1 - 2 * margin) / (asc - desc)
    pen, x = SVGPathPen(gs), margin * height / scale
    for ch in text:
        name = cmap.get(ord(ch))
        if name is None:
            continue
        gs[name].draw(TransformPen(pen, (1, 0, 0, 1, x, 0)))
        x += hmtx[name][0]
    width = int(round(x * scale + margin * height))
    del upm
    tf = f"matrix({scale} 0 0 {-scale} 0 {margin * height + asc * scale})"
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" viewBox="0 0 {width} {height}">'
            f'<path transform="{tf}" d="{pen.getCommands()}"/></svg>'), width


def degrade(clean: np.ndarray, rng: np.random.Generator) -> bytes:
    """A scan or phone photo of the black-on-white ``clean (H, W, 3)``: tinted paper and ink,
    light falling off across the page, blur, noise, JPEG quality 40."""
    h, w, _ = clean.shape
    yy, xx = np.mgrid[0:h, 0:w] / max(h, w)
    ang = rng.uniform(0, 2 * np.pi)
    ramp = np.cos(ang) * xx + np.sin(ang) * yy
    ramp = (ramp - ramp.min()) / max(np.ptp(ramp), 1e-9)
    light = 0.97 - rng.uniform(0.25, 0.4) * ramp ** 1.5
    paper = np.array([0.98, 0.95, 0.87]) - rng.uniform(0, 0.05)
    ink = np.array([0.1, 0.1, 0.14]) + rng.uniform(0, 0.06)
    a = 1 - clean.mean(-1, keepdims=True)
    img = (paper * (1 - a) + ink * a) * light[..., None]
    blurred = Image.fromarray(np.round(np.clip(img, 0, 1) * 255).astype(np.uint8))
    blurred = blurred.filter(ImageFilter.GaussianBlur(rng.uniform(0.8, 1.5)))
    noisy = np.asarray(blurred, np.float64) / 255 + rng.normal(0, rng.uniform(0.03, 0.05), img.shape)
    return _jpeg(noisy, 40)


def _om_svg(src: Path, name: str) -> str:
    import json

    data = json.loads((src / "om" / "package" / "icons.json").read_text())
    w, h = data.get("width", 72), data.get("height", 72)
    return f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w} {h}">{data["icons"][name]["body"]}</svg>'


def _fa(src: Path, names: list[str]) -> list[tuple[str, str]]:
    d = src / "fa" / "package" / "svgs" / "solid"
    return [(n, (d / f"{n}.svg").read_text()) for n in names]


def _stroked(svg: str, width_px: float, size: int) -> str:
    """``svg`` (a Font Awesome icon) drawn as ``width_px`` px black strokes at ``size`` px, unfilled."""
    vb = [float(v) for v in re.search(r'viewBox="([^"]+)"', svg).group(1).split()]
    sw = width_px * max(vb[2], vb[3]) / size
    svg = re.sub(r'\s(fill|stroke|stroke-width)="[^"]*"', "", re.sub(r"<!--.*?-->", "", svg))
    return re.sub(r"<path ", f'<path fill="none" stroke="black" stroke-width="{sw:.3f}" ', svg)


def curves_svg(rng: np.random.Generator, size: int) -> str:
    """Overlapping stroked circles, lines and curves, 1-2 px wide, at ``size`` px."""
    parts = []
    for _ in range(int(rng.integers(3, 6))):
        (x, y), r = rng.uniform(0.25, 0.75, 2) * size, rng.uniform(0.1, 0.25) * size
        parts.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="{r:.1f}" fill="none" stroke="black" '
                     f'stroke-width="{rng.uniform(1, 2):.2f}"/>')
    for _ in range(int(rng.integers(2, 4))):
        p = rng.uniform(0.08, 0.92, (4, 2)) * size
        parts.append(f'<path d="M {p[0, 0]:.1f} {p[0, 1]:.1f} C {p[1, 0]:.1f} {p[1, 1]:.1f} {p[2, 0]:.1f} '
                     f'{p[2, 1]:.1f} {p[3, 0]:.1f} {p[3, 1]:.1f}" fill="none" stroke="black" '
                     f'stroke-width="{rng.uniform(1, 2):.2f}" stroke-linecap="round"/>')
    return f'<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{size}">{"".join(parts)}</svg>'


def _sprite(svg: str, side: int, colors: int) -> np.ndarray:
    """``svg`` as a ``side`` px sprite of at most ``colors`` colours (no dithering), upscaled 8x."""
    small = Image.fromarray(np.round(rasterize_svg(svg, side, side) * 255).astype(np.uint8))
    small = small.quantize(colors, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).convert("RGB")
    return np.asarray(small.resize((side * 8, side * 8), Image.NEAREST), np.float64) / 255


def make_sets(src: Path, names: list[str], limit: int | None) -> dict[str, list[dict]]:
    """Per set, its pictures: ``name``, ``input`` (file bytes, PNG or JPEG) and ``clean`` (the
    picture it was made from, ``(H, W, 3)`` in [0, 1])."""
    rng = np.random.default_rng(0)
    fonts = dict(held_out_fonts(lambda f: f in {("FreeSans", "Bold"), ("FreeSerif", "Regular"),
                                                ("Lato", "Black"), ("Lato", "Regular"), ("FreeSerif", "Bold")}))
    sets: dict[str, list[dict]] = {}
    if "scans" in names:
        rows = []
        for i, (face, ch) in enumerate([(("FreeSans", "Bold"), "g"), (("FreeSerif", "Regular"), "R"),
                                        (("Lato", "Black"), "&"), (("Lato", "Regular"), "B")]):
            size = int(rng.integers(400, 601))
            svg, w = text_svg(fonts[face], ch, size)
            svg = svg.replace(f'width="{w}"', f'width="{size}"').replace(f"0 0 {w} ", f"0 0 {size} ")
            rows.append({"name": f"glyph{i}", "svg": svg, "size": (size, size)})
        for i, word in enumerate(WORDS):
            svg, w = text_svg(fonts[[("Lato", "Regular"), ("FreeSerif", "Bold"), ("FreeSans", "Bold")][i]], word, 160)
            rows.append({"name": f"word{i}", "svg": svg, "size": (w, 160)})
        for name, svg in _fa(src, ["house", "camera", "bicycle"]):
            rows.append({"name": name, "svg": svg, "size": (500, 500)})
        for name, svg in _fa(src, ["gear", "tree"]):  # large scans
            rows.append({"name": f"{name} (1024 px)", "svg": svg, "size": (1024, 1024)})
        for r in rows:
            r["clean"] = rasterize_svg(r["svg"], *r["size"])
            r["input"] = degrade(r["clean"], rng)
        sets["scans"] = rows
    if "logos" in names:
        rows = []
        for i, n in enumerate(LOGOS + LARGE_LOGOS):
            side = 512 if n in LOGOS else 1024
            clean = rasterize_svg(_om_svg(src, n), side, side)
            rows.append({"name": n + (" (jpeg)" if i % 2 else "") + (f" ({side} px)" if side > 512 else ""),
                         "clean": clean, "input": _jpeg(clean, 70) if i % 2 else _png(clean)})
        sets["logos"] = rows
    if "pixel" in names:
        rows = []
        for i, n in enumerate(SPRITES):
            clean = _sprite(_om_svg(src, n), [16, 24, 32][i % 3], 12)
            rows.append({"name": n, "clean": clean, "input": _png(clean)})
        sets["pixel"] = rows
    if "line" in names:
        rows = []
        for n, svg in _fa(src, ["bicycle", "camera", "star", "gear"]):
            clean = rasterize_svg(_stroked(svg, 1.5, 512), 512, 512)
            rows.append({"name": n, "clean": clean, "input": _png(clean)})
        for i in range(4):
            clean = rasterize_svg(curves_svg(rng, 512), 512, 512)
            rows.append({"name": f"curves{i}", "clean": clean, "input": _png(clean)})
        sets["line"] = rows
    if "photos" in names:
        import skimage.data

        rows = []
        for n in ("astronaut", "coffee", "chelsea"):
            clean = getattr(skimage.data, n)() / 255.0
            rows.append({"name": n, "clean": clean, "input": _png(clean)})
        sets["photos"] = rows
    if "large" in names:
        font = fonts[("FreeSerif", "Regular")]
        lines = ["The quick brown fox", "jumps over the lazy", "dog; 0123456789", "Pack my box with",
                 "five dozen jugs."]
        page = np.ones((2048, 2048, 3))
        for k, line in enumerate(lines):
            svg, w = text_svg(font, line, 300)
            img = rasterize_svg(svg, w, 300)[:, :1900]
            page[100 + 370 * k : 400 + 370 * k, 74 : 74 + img.shape[1]] = img
        sets["large"] = [{"name": "page2048", "clean": page, "input": degrade(page, rng)}]
    for name in sets:
        sets[name] = sets[name][:limit] if limit else sets[name]
    return sets


# --- the tools ------------------------------------------------------------------------------------


def im2vec(path: Path, out: Path, *args: str) -> tuple[str, float, int]:
    """The SVG, the wall time (process start included) and the peak memory (bytes) of
    ``im2vec vectorize path -o out args``; an error line as the SVG when it fails."""
    cmd = [sys.executable, "-m", "im2vec_cli", "vectorize", str(path), "-o", str(out), *args]
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    peak_file = out.with_suffix(".peak")
    # GNU time measures the peak of its own child: a child of this process would inherit this
    # process's peak (Linux keeps ru_maxrss across fork and exec)
    timer = ["/usr/bin/time", "-f", "%M", "-o", str(peak_file)] if Path("/usr/bin/time").exists() else []
    t = time.perf_counter()
    proc = subprocess.run(timer + cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    wall = time.perf_counter() - t
    peak = int(peak_file.read_text().split()[-1]) * 1024 if timer and peak_file.exists() else 0
    if proc.returncode:
        return "error: " + (proc.stderr.decode().strip().splitlines() or ["failed"])[-1], wall, peak
    return out.read_text(), wall, peak


def vtracer(png: bytes, mode: str) -> str:
    import vtracer as vt

    return vt.convert_raw_image_to_svg(png, img_format="png", colormode=mode)


def _as_png(data: bytes) -> bytes:
    buf = io.BytesIO()
    Image.open(io.BytesIO(data)).convert("RGB").save(buf, "PNG")
    return buf.getvalue()


_MODEL = []


def _model():
    """The default model, loaded once (in-process timings leave its loading out)."""
    if not _MODEL:
        from im2vec_cli import api

        _MODEL.append(api.load_model("fonts", "cpu"))
    return _MODEL[0]


def tools(name: str) -> dict:
    """Tool name -> ``fn(row, workdir) -> (svg, seconds, peak bytes or None)``."""
    def cli(*args):
        def fn(r, d):
            path = d / ("in.jpg" if r["input"][:2] == b"\xff\xd8" else "in.png")
            path.write_bytes(r["input"])
            out = d / "out.svg"
            out.unlink(missing_ok=True)
            return im2vec(path, out, *args)
        return fn

    def timed(f):
        def fn(r, d):
            png = _as_png(r["input"])
            t = time.perf_counter()
            svg = f(png)
            return svg, time.perf_counter() - t, None
        return fn

    def in_process(r, d):  # the work alone, without the start-up (the model loaded once, beforehand)
        from im2vec_cli import api
        from im2vec_cli.files import load_image

        img = load_image("in.png", _as_png(r["input"]))
        t = time.perf_counter()
        svg = api.vectorize(img, _model(), effort="draft").to_svg()
        return svg, time.perf_counter() - t, None

    out = {"im2vec": cli(), "im2vec --effort draft": cli("--effort", "draft"),
           "im2vec --effort draft, in process": in_process}
    if name in TWO_TONE:
        out["potrace"] = timed(potrace)
        out["vtracer (binary)"] = timed(lambda png: vtracer(png, "binary"))
    out["vtracer (color)"] = timed(lambda png: vtracer(png, "color"))
    return out


# --- scoring --------------------------------------------------------------------------------------


def topology(rgb: np.ndarray, level: float = 0.5) -> tuple[int, int]:
    """Pieces and holes of the ink (darker than ``level``) of at least 16 px (``outlines._topology``)."""
    return _topology(rgb.mean(-1) < level)


LINE_LEVEL = 0.75  # line art's ink: any pixel a 1 px stroke darkens by a quarter (at 0.5, a 1 px stroke's
# anti-aliased pixels break it into dashes, in the clean picture as in any output)


def score(name: str, rows: list[dict], got: list[tuple[str, float, int | None]]) -> dict:
    mse, topo, paths, segs, times, peaks, failed, small = [], [], [], [], [], [], 0, []
    for r, (svg, sec, peak) in zip(rows, got):
        times.append(sec)
        if max(r["clean"].shape[:2]) <= SMALL_SIDE:
            small.append(sec)
        if peak:
            peaks.append(peak)
        if svg.startswith("error:"):
            failed += 1
            continue
        h, w, _ = r["clean"].shape
        out = rasterize_svg(svg, w, h)
        mse.append(float(((out - r["clean"]) ** 2).mean()))
        if name in TWO_TONE:
            level = LINE_LEVEL if name == "line" else 0.5
            topo.append(topology(out, level) == topology(r["clean"], level))
        paths.append(svg.count("<path"))
        segs.append(svg_structure(svg)[0])
    row = {"mse": np.mean(mse) if mse else float("nan"), "paths": np.mean(paths) if paths else 0,
           "segments": np.mean(segs) if segs else 0, "s": statistics.median(times), "failed": failed,
           "s_small": statistics.median(small) if small else None,
           "peak": max(peaks) if peaks else None}
    if name in TWO_TONE:
        row["topology"] = np.mean(topo) if topo else 0.0
    return row


# --- contact sheets -------------------------------------------------------------------------------


def _crop_box(clean: np.ndarray, side: int) -> tuple[int, int]:
    """The top-left corner of the ``side`` px square of ``clean`` holding the most edges."""
    from scipy.ndimage import uniform_filter

    g = clean.mean(-1)
    edges = np.abs(np.diff(g, axis=0, prepend=g[:1])) + np.abs(np.diff(g, axis=1, prepend=g[:, :1]))
    h, w = g.shape
    side = min(side, h, w)
    dens = uniform_filter(edges, side, mode="constant")
    half = side // 2
    inner = dens[half : h - side + half + 1, half : w - side + half + 1]
    y, x = np.unravel_index(np.argmax(inner), inner.shape)
    return int(y), int(x)


def sheet(rows: list[dict], outs: dict[str, list[str]], path: Path, side: int = 96) -> None:
    """Per picture one row: its input, the clean picture and each tool's SVG, a ``side`` px crop
    at ``UP``x (nearest-neighbour for the rasters, rendered at ``UP``x for the SVGs)."""
    cols = ["input", "clean", *outs]
    tile = side * UP
    img = Image.new("RGB", (tile * len(cols), tile * len(rows) + 20 * len(rows)), "white")
    from PIL import ImageDraw

    draw = ImageDraw.Draw(img)
    for i, r in enumerate(rows):
        h, w, _ = r["clean"].shape
        s = min(side, h, w)
        y, x = _crop_box(r["clean"], s)
        inp = np.asarray(Image.open(io.BytesIO(r["input"])).convert("RGB"), np.float64) / 255
        tiles = [inp, r["clean"]]
        for tool in outs:
            svg = outs[tool][i]
            if svg.startswith("error:"):
                tiles.append(None)
                continue
            big = rasterize_svg(svg, w * UP, h * UP) if w * h <= 1024 * 1024 else None
            tiles.append(big)
        top = i * (tile + 20)
        for j, t in enumerate(tiles):
            if t is None:
                continue
            if j < 2:
                crop = np.kron(t[y : y + s, x : x + s], np.ones((UP, UP, 1)))
            else:
                crop = t[y * UP : (y + s) * UP, x * UP : (x + s) * UP]
            img.paste(Image.fromarray(np.round(crop * 255).astype(np.uint8)), (j * tile, top + 20))
            draw.text((j * tile + 4, top + 4), f"{cols[j]}: {r['name']}" if j == 0 else cols[j], fill="black")
    img.save(path)


# --- the run ----------------------------------------------------------------------------------------


def _line(tool: str, r: dict) -> str:
    topo = f"topology {r['topology']:.0%}  " if "topology" in r else ""
    peak = f"  peak {r['peak'] / 2**20:.0f} MB" if r["peak"] else ""
    small = f" ({r['s_small']:.2f} s at <= {SMALL_SIDE} px)" if r["s_small"] is not None else ""
    return (f"{tool:24s} MSE {r['mse']:.5f}  {topo}paths {r['paths']:.1f}  segments {r['segments']:.0f}  "
            f"{r['s']:.2f} s{small}{peak}  failed {r['failed']}")


def markdown(results: dict, sizes: dict, sheets: dict) -> str:
    lines = [f"# The pictures people bring\n\nWritten by `make bench-realworld` "
             f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} CPU cores). All tools on "
             "the same pictures in one run; the sets and metrics are described in bench/realworld.py. MSE is "
             "against the clean picture each input was made from (photos: against the input); im2vec's time is "
             "the whole command, process start included, and its peak is the process's.\n"]
    for name, rows in results.items():
        lines += [f"\n## {name}: {sizes[name]} pictures\n",
                  f"| tool | MSE | topology | paths | segments | s / picture (median) | s / picture of <= {SMALL_SIDE} px "
                  "(median) | peak MB | failed |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for tool, r in rows.items():
            topo = f"{r['topology']:.0%}" if "topology" in r else "–"
            peak = f"{r['peak'] / 2**20:.0f}" if r["peak"] else "–"
            small = f"{r['s_small']:.2f}" if r["s_small"] is not None else "–"
            lines.append(f"| {tool} | {r['mse']:.5f} | {topo} | {r['paths']:.1f} | {r['segments']:.0f} | "
                         f"{r['s']:.2f} | {small} | {peak} | {r['failed']} |")
        if name in sheets:
            lines.append(f"\n![{name}]({sheets[name]})")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--src", default=str(ROOT / "bench" / ".sets"), help="folder holding fa/ and om/")
    ap.add_argument("--sets", default=",".join(SETS))
    ap.add_argument("--tools", default=None, help="comma-separated substrings of the tools to run")
    ap.add_argument("--limit", type=int, default=None)
    ap.add_argument("--markdown", default=None, help="write the table here (and the sheets beside it)")
    ap.add_argument("--dump", default=None, help="write every input and SVG here")
    args = ap.parse_args()
    names = [s for s in args.sets.split(",") if s]
    sets = make_sets(Path(args.src), names, args.limit)
    results, sizes, sheets = {}, {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, rows in sets.items():
            sizes[name] = len(rows)
            results[name], outs = {}, {}
            for tool, fn in tools(name).items():
                if args.tools and not any(t in tool for t in args.tools.split(",")):
                    continue
                got = [fn(r, Path(tmp)) for r in rows]
                outs[tool] = [g[0] for g in got]
                results[name][tool] = score(name, rows, got)
                print(f"{name:7s} {_line(tool, results[name][tool])}", flush=True)
                if args.dump:
                    d = Path(args.dump, name)
                    d.mkdir(parents=True, exist_ok=True)
                    for r, svg in zip(rows, outs[tool]):
                        (d / f"{r['name']}.{re.sub(r'[^a-z0-9]+', '_', tool)}.svg").write_text(svg)
                        (d / f"{r['name']}.input").write_bytes(r["input"])
            if args.markdown and name != "large":
                folder = Path(args.markdown).parent / "realworld"
                folder.mkdir(parents=True, exist_ok=True)
                sheet(rows[:4], {t: o[:4] for t, o in outs.items() if "draft" not in t and "binary" not in t},
                      folder / f"{name}.png")
                sheets[name] = f"{folder.name}/{name}.png"
    if args.markdown:
        Path(args.markdown).write_text(markdown(results, sizes, sheets))


if __name__ == "__main__":
    main()
