"""Large and pathological pictures as real processes (issue "Hardening, round 3"): each under
an 8 GiB address-space cap (``RLIMIT_AS``) and its own time bound. Prints one row per case:
exit code, the ``Error:`` line, whether a traceback appeared, seconds, peak resident memory,
and for a vectorized picture the MSE of its SVG rendered back (cairosvg) against the input.

    python bench/hardening.py [--out docs/hardening-run.md] [--only NAME ...]

It prints figures; it passes or fails nothing (the tests in tests/cli/test_batches.py,
tests/cli/test_bad_input.py and tests/trace/ check each behaviour on small cases).
"""

from __future__ import annotations

import argparse
import io
import os
import resource
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFilter, ImageFont

CAP = 8 * 2**30
EXE = [sys.executable, "-m", "im2vec_cli"]


def _cap():
    resource.setrlimit(resource.RLIMIT_AS, (CAP, CAP))


def run(args, cwd, limit, term_after=None):
    """(exit code or "killed", stderr, seconds, peak RSS MiB). ``term_after``: SIGTERM then."""
    start = time.perf_counter()
    with open(cwd / "stderr.txt", "w+") as err:
        p = subprocess.Popen(EXE + args, cwd=cwd, stdout=subprocess.DEVNULL, stderr=err, stdin=subprocess.DEVNULL,
                             preexec_fn=_cap)
        killer = threading.Timer(limit, p.kill)
        killer.start()
        if term_after is not None:
            threading.Timer(term_after, lambda: p.poll() is None and p.send_signal(signal.SIGTERM)).start()
        _, status, ru = os.wait4(p.pid, 0)
        p.returncode = os.waitstatus_to_exitcode(status)
        killed = not killer.is_alive() and p.returncode < 0
        killer.cancel()
        err.seek(0)
        text = err.read()
    code = "killed" if killed else p.returncode
    return code, text, time.perf_counter() - start, ru.ru_maxrss / 1024


def blocks(size: int, block: int, colors: int, seed: int = 0) -> np.ndarray:
    """``(size, size, 3)`` uint8: ``block``-px squares, each one of ``colors`` random colours."""
    rng = np.random.default_rng(seed)
    palette = rng.integers(0, 256, (colors, 3), dtype=np.uint8)
    n = -(-size // block)
    grid = palette[rng.integers(0, colors, (n, n))]
    return np.kron(grid, np.ones((block, block, 1), np.uint8))[:size, :size]


def scan(seed: int, w: int, h: int) -> Image.Image:
    """A phone photo / scan of a drawing: strokes and scribbles on paper, uneven light, noise."""
    rng = np.random.default_rng(seed)
    img = Image.new("L", (w, h), 245)
    d = ImageDraw.Draw(img)
    for _ in range(int(rng.integers(8, 20))):
        pts = [tuple(int(v) for v in rng.uniform(20, [w - 20, h - 20])) for _ in range(int(rng.integers(3, 9)))]
        d.line(pts, fill=int(rng.integers(10, 60)), width=int(rng.integers(1, 6)), joint="curve")
    for _ in range(int(rng.integers(2, 6))):
        x, y, r = rng.uniform(40, w - 40), rng.uniform(40, h - 40), rng.uniform(8, 40)
        d.ellipse((x - r, y - r, x + r, y + r), outline=int(rng.integers(10, 60)), width=int(rng.integers(1, 4)))
    a = np.asarray(img.filter(ImageFilter.GaussianBlur(0.8)), np.float64)
    yy, xx = np.mgrid[0:h, 0:w]
    light = 0.65 + 0.35 * np.cos((xx / w - rng.uniform()) * 2.5) * np.cos((yy / h - rng.uniform()) * 2)
    a = a * light + rng.normal(0, 6, a.shape)
    rgb = np.stack([a, a * 0.97, a * 0.92], -1).clip(0, 255).astype(np.uint8)  # warm paper
    return Image.fromarray(rgb)


def dither(w: int, h: int) -> Image.Image:
    """A 1-bit ordered (4 x 4 Bayer) dither of wavy shading: grain, so vectorized at the copy, where its
    shades' bands have long outlines to simplify (``trace.simplify``: 62 s at O(S^2), 34 s with its heap)."""
    yy, xx = np.mgrid[0:h, 0:w]
    bayer = (np.array([[0, 8, 2, 10], [12, 4, 14, 6], [3, 11, 1, 9], [15, 7, 13, 5]]) + 0.5) / 16
    shade = 0.1 + 0.8 * xx / w + 0.1 * np.sin(yy * 2 * np.pi / 320)
    return Image.fromarray(shade > bayer[yy % 4, xx % 4])


def make(d: Path) -> dict[str, tuple[list[str], int, str | None]]:
    """The input files, and the cases: name -> (arguments, time bound s, picture to compare)."""
    rng = np.random.default_rng(0)
    Image.fromarray(blocks(256, 8, 20)).save(d / "blocks256.png")
    Image.fromarray(rng.integers(0, 256, (1024, 1024, 3), dtype=np.uint8)).save(d / "noise1024.png")
    checker = ((np.indices((1024, 1024)).sum(0) % 2) * 255).astype(np.uint8)
    Image.fromarray(checker).convert("RGB").save(d / "checker1024.png")
    yy, xx = np.mgrid[0:2048, 0:2048] / 2047
    grad = np.stack([xx, yy, 1 - (xx + yy) / 2], -1) * 255
    Image.fromarray(grad.astype(np.uint8)).save(d / "gradient2048.png")
    Image.fromarray(rng.integers(0, 256, (4096, 4096, 3), dtype=np.uint8)).save(d / "noise4096.png")
    Image.fromarray(blocks(8000, 40, 12)).save(d / "blocks8000.png")
    pts = " ".join(f"L {x:.1f} {y:.1f}" for x, y in rng.uniform(0, 1000, (5000, 2)))
    (d / "lines5000.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" width="1000" height="1000">'
                                     f'<path d="M 500 500 {pts} Z"/></svg>')
    (d / "dash.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100"><line x1="0" '
                                'y1="50" x2="100" y2="50" stroke="black" stroke-width="2" stroke-dasharray="0.0125"/>'
                                '</svg>')
    clip = Image.new("RGB", (512, 512), "white")  # flat circles drawn without anti-aliasing: curves, not pixel art
    palette = [tuple(int(c) for c in rng.integers(0, 256, 3)) for _ in range(10)]
    for i in range(120):
        x, y, r = *rng.uniform(0, 512, 2), rng.uniform(3, 64)
        ImageDraw.Draw(clip).ellipse((x - r, y - r, x + r, y + r), fill=palette[i % 10])
    clip.save(d / "clipart512.png")
    page = Image.new("1", (2550, 3300), 1)  # a 300 dpi 1-bit page of text: traced whole (options.MAX_BILEVEL_PIXELS)
    font = ImageFont.load_default(size=34)
    for y in range(150, 3150, 60):
        ImageDraw.Draw(page).text((150, y), " ".join(f"word{(y * 7 + i) % 97}" for i in range(24)), font=font, fill=0)
    page.save(d / "page1bit.png")
    Image.fromarray(checker.repeat(4, 0).repeat(4, 1)).convert("1").save(d / "checker1bit.png")  # grain: the copy,
    # where its 4 px squares are 2 px ones, read as pixel art
    dither(4000, 3000).save(d / "dither1bit.png")
    (d / "scans").mkdir()
    for i in range(10):
        w, h = (int(v) for v in rng.integers(400, 601, 2))
        buf = io.BytesIO()
        scan(i, w, h).save(buf, format="JPEG", quality=int(rng.integers(55, 85)))
        (d / "scans" / f"page{i}.jpg").write_bytes(buf.getvalue())
    (d / "glyphs").mkdir()
    for i in range(200):
        g = Image.new("L", (64, 64), 255)
        ImageDraw.Draw(g).ellipse((8 + i % 5, 8, 56, 56 - i % 7), outline=0, width=6 + i % 3)
        g.save(d / "glyphs" / f"g{i:02d}.png")
    return {
        "blocks 256² (8 px, 20 colours)": (["vectorize", "blocks256.png", "-o", "blocks256.svg"], 60, "blocks256.png"),
        "hard-edged clip art 512² (120 flat circles)": (["vectorize", "clipart512.png", "-o", "clipart512.svg"], 60,
                                                         "clipart512.png"),
        "RGB noise 1024²": (["vectorize", "noise1024.png", "-o", "noise1024.svg"], 90, "noise1024.png"),
        "checkerboard 1024² (1 px)": (["vectorize", "checker1024.png", "-o", "checker1024.svg"], 90, "checker1024.png"),
        "colour gradient 2048²": (["vectorize", "gradient2048.png", "-o", "gradient2048.svg"], 90, "gradient2048.png"),
        "1-bit page of text 2550 x 3300 (300 dpi, traced whole)": (["vectorize", "page1bit.png", "-o", "page1bit.svg"],
                                                                    120, "page1bit.png"),
        "1-bit checkerboard 4096² (4 px)": (["vectorize", "checker1bit.png", "-o", "checker1bit.svg"], 120, None),
        "1-bit ordered dither 4000 x 3000": (["vectorize", "dither1bit.png", "-o", "dither1bit.svg"], 120, "dither1bit.png"),
        "RGB noise 4096²": (["vectorize", "noise4096.png", "-o", "noise4096.svg"], 120, None),
        "blocks 8000² (40 px, 12 colours)": (["vectorize", "blocks8000.png", "-o", "blocks8000.svg"], 120, None),
        "render: one path of 5,000 random lines": (["render", "lines5000.svg", "-o", "lines.png"], 60, None),
        "render: stroke-dasharray 0.0125": (["render", "dash.svg", "-o", "dash.png"], 60, None),
        "10 scanned pages (JPEG, 400-600 px)": (["vectorize", "scans", "-o", "scans_out"], 120, None),
    }


def mse_back(svg: Path, png: Path) -> str:
    """The MSE of the SVG rendered by cairosvg at the input's size against the input."""
    from im2vec_cli.vector import rasterize_svg

    if not svg.exists():
        return ""
    with Image.open(png) as im:
        ref = np.asarray(im.convert("RGB"), np.float64) / 255
    got = rasterize_svg(svg.read_text(), ref.shape[1], ref.shape[0])
    return f"{float(((got - ref) ** 2).mean()):.5f}"


def sigterm_case(d: Path) -> str:
    """SIGTERM into ``vectorize --jobs 2`` over 200 glyphs once the first SVGs are written: exit
    code, children left after 3 s, a resource-tracker warning, SVGs written, temp files."""
    out = d / "term_out"
    p = subprocess.Popen(EXE + ["vectorize", "glyphs", "-o", str(out), "--jobs", "2", "--model", "fonts"], cwd=d,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, preexec_fn=_cap)
    deadline = time.time() + 120
    while time.time() < deadline and not (out.exists() and any(out.glob("g*.svg"))):
        time.sleep(0.2)
    p.send_signal(signal.SIGTERM)
    err = p.communicate(timeout=60)[1]
    time.sleep(3)
    left = subprocess.run(["pgrep", "-f", "im2vec_cli|multiprocessing"], capture_output=True, text=True).stdout.split()
    left = [x for x in left if int(x) != os.getpid()]
    svgs = list(out.glob("*.svg")) if out.exists() else []
    temps = [x for x in out.iterdir() if x.name.startswith(".")] if out.exists() else []
    return (f"| SIGTERM into `vectorize --jobs 2` of 200 glyphs | {p.returncode} | "
            f"{'resource_tracker warning' if 'resource_tracker' in err else ''} | "
            f"{'yes' if 'Traceback' in err else 'no'} | {len(left)} processes left after 3 s, {len(svgs)} SVGs, "
            f"{len(temps)} temp files | | |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None, help="Also write the table to this markdown file.")
    ap.add_argument("--only", nargs="*", default=None, help="Run only the cases whose names contain these words.")
    args = ap.parse_args()
    rows = ["| case | exit | `Error:` line | traceback | s (bound) | peak RSS MiB | MSE back |",
            "|---|---|---|---|---|---|---|"]
    print("\n".join(rows), flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        for name, (argv, bound, picture) in make(d).items():
            if args.only and not any(w in name for w in args.only):
                continue
            code, err, secs, peak = run(argv, d, bound + 30)
            errors = [x for x in err.splitlines() if x.startswith("Error:")]
            note = "; ".join(e[7:80] for e in errors[:2]) + (f" (+{len(errors) - 2})" if len(errors) > 2 else "")
            back = mse_back(d / argv[3], d / picture) if picture and code == 0 else ""
            rows.append(f"| {name} | {code} | {note} | {'yes' if 'Traceback' in err else 'no'} | {secs:.1f} ({bound}) "
                        f"| {peak:.0f} | {back} |")
            print(rows[-1], flush=True)
        if not args.only or any("SIGTERM" in w for w in args.only):
            rows.append(sigterm_case(d))
            print(rows[-1], flush=True)
    rows.append(f"\nRLIMIT_AS {CAP // 2**30} GiB, {os.cpu_count()} cores, uid {os.getuid()}.")
    if args.out:
        Path(args.out).write_text("\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
