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
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

from im2vec_cli.vector import rasterize_svg  # noqa: E402
from outlines import _topology  # noqa: E402
from vectorize import potrace, svg_structure  # noqa: E402

UP = 4  # contact sheets: crops at 4x
SMALL_SIDE = 600  # the time target is per picture of at most this many px a side (the 400-600 px ones)
SETS = ("scans", "logos", "pixel", "line", "photos", "large")
TWO_TONE = {"scans", "line", "large"}
from realworld_sets import make_sets  # noqa: E402

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
