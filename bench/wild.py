"""The pictures nobody made for it (issue 69): im2vec, potrace and vtracer on real files
(bench/wild_sets.py: icons, clip art, logos, photos, scanned pages, screenshots, drawings),
side by side in one run.

Tools: ``im2vec vectorize FOLDER -o OUT`` (one command for the whole folder, as a user runs it);
potrace (the picture's grey at 0.5, ``potrace -s``); vtracer (colour, its defaults, on the picture
over white). Every picture is taken as it looks: over white where it is transparent.

Scores, per picture and tool:

- **MSE** at 1x: the SVG rendered by cairosvg at the picture's size against the picture over white
  (RGB in [0, 1]);
- **edge F1**: the picture's Canny edges against the render's (both grey, blurred by a Gaussian of
  sigma 1, thresholds 50 and 150), an edge found where the other has one within 1.5 px: lost
  outlines cost recall, blotches and streaks precision;
- **OCR** (pages and screenshots with a true text in bench/wild_text/): tesseract's reading of the
  SVG rendered at 3x (at most 4096 px a side) against the true text, as difflib's ratio of the two
  with runs of white space made one; the picture itself is read the same way, for reference.

A picture counts as **at or above** when im2vec's MSE is at most the better peer's, its edge F1 at
least the better peer's and its OCR (where scored) at least the better peer's, each metric's better
peer taken alone (a tie within ``TIE``: a thousandth of the MSE scale, 0.005 of F1 and of OCR).
Pictures kept aside (a third, bench/wild_sets.aside) are reported apart.

Run: ``make bench-wild`` (the sets first: ``make bench-sets``), or
``python bench/wild.py [--src bench/.sets] [--only SUBSTR] [--markdown docs/WILD.md]``.
"""

from __future__ import annotations

import argparse
import difflib
import io
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

from im2vec_cli.vector import rasterize_svg  # noqa: E402
from vectorize import potrace, svg_structure  # noqa: E402
from wild_sets import make_wild  # noqa: E402

TOOLS = ("im2vec", "potrace", "vtracer")
TIE = {"mse": 1e-3, "f1": 0.005, "ocr": 0.005}  # MSE: relative to the better peer's plus 1e-5 absolute
TEXT_DIR = ROOT / "bench" / "wild_text"
OCR_SIDE = 4096


def over_white(path: Path) -> np.ndarray:
    """The picture as it looks: ``(H, W, 3)`` float64 in [0, 1], over white where transparent.
    Read here with Pillow, not through im2vec's own ``files.load_picture``: the reference a tool is
    scored against does not pass through the tool."""
    with Image.open(path) as im:
        rgba = np.asarray(im.convert("RGBA"), np.float64) / 255
    return rgba[..., :3] * rgba[..., 3:] + (1 - rgba[..., 3:])


def _png(rgb: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.round(rgb * 255).astype(np.uint8)).save(buf, "PNG")
    return buf.getvalue()


# --- the tools ------------------------------------------------------------------------------------


def run_im2vec(folder: Path, out: Path) -> tuple[dict[str, str], float]:
    """Each picture's SVG (or ``error: ...``, its line from stderr) and the wall time of one
    ``im2vec vectorize folder -o out`` command."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    cmd = [sys.executable, "-m", "im2vec_cli", "vectorize", str(folder), "-o", str(out)]
    t = time.perf_counter()
    proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    wall = time.perf_counter() - t
    lines = proc.stderr.decode().strip().splitlines()
    got = {}
    for f in sorted(folder.iterdir()):
        svg = out / (f.stem + ".svg")
        if svg.exists():
            got[f.name] = svg.read_text()
        else:  # its own error line, else the command's last
            got[f.name] = "error: " + next((ln for ln in lines if f.name in ln), lines[-1] if lines else "failed")
    return got, wall


def run_peer(tool: str, rgb: np.ndarray) -> tuple[str, float]:
    png = _png(rgb)
    t = time.perf_counter()
    if tool == "potrace":
        svg = potrace(png)
    else:
        import vtracer

        svg = vtracer.convert_raw_image_to_svg(png, img_format="png", colormode="color")
    return svg, time.perf_counter() - t


# --- scoring --------------------------------------------------------------------------------------


def edges(rgb: np.ndarray) -> np.ndarray:
    grey = np.round((rgb @ np.array([0.299, 0.587, 0.114])) * 255).astype(np.uint8)
    return cv2.Canny(cv2.GaussianBlur(grey, (0, 0), 1.0), 50, 150) > 0


def edge_f1(picture: np.ndarray, render: np.ndarray, within: float = 1.5) -> float:
    a, b = edges(picture), edges(render)
    if not a.any() and not b.any():
        return 1.0
    if not a.any() or not b.any():
        return 0.0
    near_a = cv2.distanceTransform((~a).astype(np.uint8), cv2.DIST_L2, 5) <= within
    near_b = cv2.distanceTransform((~b).astype(np.uint8), cv2.DIST_L2, 5) <= within
    precision, recall = (b & near_a).sum() / b.sum(), (a & near_b).sum() / a.sum()
    return float(2 * precision * recall / max(precision + recall, 1e-12))


def ocr(rgb: np.ndarray) -> str:
    """tesseract's reading of ``rgb``, white space made single spaces."""
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "page.png"
        p.write_bytes(_png(rgb))
        out = subprocess.run(["tesseract", str(p), "-", "--psm", "3"], capture_output=True, text=True)
    return " ".join(out.stdout.split())


def ocr_scale(w: int, h: int) -> float:
    return max(1.0, min(3.0, OCR_SIDE / max(w, h)))


def text_score(read: str, truth: str) -> float:
    return difflib.SequenceMatcher(None, read, " ".join(truth.split()), autojunk=False).ratio()


def score(svg: str, picture: np.ndarray, truth: str | None) -> dict:
    h, w, _ = picture.shape
    if svg.startswith("error:"):
        return {"error": svg[7:]}
    render = rasterize_svg(svg, w, h)
    segs, _ = svg_structure(svg)
    out = {"mse": float(((render - picture) ** 2).mean()), "f1": edge_f1(picture, render),
           "paths": len(re.findall(r"<path\b", svg)), "segments": segs, "bytes": len(svg.encode())}
    if truth is not None:
        s = ocr_scale(w, h)
        out["ocr"] = text_score(ocr(rasterize_svg(svg, round(w * s), round(h * s))), truth)
    return out


def verdict(r: dict) -> tuple[bool, list[str]]:
    """Whether im2vec is at or above the better peer on every metric, and the metrics it misses."""
    me, missed = r["im2vec"], []
    if "error" in me:
        return False, ["error"]
    peers = [r[t] for t in TOOLS[1:] if "error" not in r[t]]
    if not peers:
        return True, []
    best = min(p["mse"] for p in peers)
    if me["mse"] > best * (1 + TIE["mse"]) + 1e-5:
        missed.append("mse")
    for m in ("f1", "ocr"):
        if m in me and me[m] < max(p[m] for p in peers) - TIE[m]:
            missed.append(m)
    return not missed, missed


# --- the run ----------------------------------------------------------------------------------------


def run(src: Path, only: str | None) -> dict:
    rows = make_wild(src, src / "wild")
    if only:
        rows = [r for r in rows if only in r["file"]]
    folder = src / "wild" / "pictures"
    with tempfile.TemporaryDirectory() as d:
        sub = Path(d) / "in"
        sub.mkdir()
        for r in rows:
            (sub / r["file"]).symlink_to((folder / r["file"]).resolve())
        svgs, wall = run_im2vec(sub, Path(d) / "out")
    out_dir = src / "wild" / "svg"
    for tool in TOOLS:
        (out_dir / tool).mkdir(parents=True, exist_ok=True)
    times = {"im2vec": wall, "potrace": 0.0, "vtracer": 0.0}
    for r in rows:
        picture = over_white(folder / r["file"])
        stem = Path(r["file"]).stem
        truth_file = TEXT_DIR / f"{stem}.txt"
        truth = truth_file.read_text() if truth_file.exists() else None
        r["size"] = picture.shape[1], picture.shape[0]
        for tool in TOOLS:
            if tool == "im2vec":
                svg = svgs[r["file"]]
            else:
                svg, sec = run_peer(tool, picture)
                times[tool] += sec
            (out_dir / tool / f"{stem}.svg").write_text(svg)
            r[tool] = score(svg, picture, truth)
        if truth is not None:
            s = ocr_scale(*r["size"])
            big = np.asarray(Image.fromarray(np.round(picture * 255).astype(np.uint8)).resize(
                (round(r["size"][0] * s), round(r["size"][1] * s)), Image.LANCZOS), np.float64) / 255
            r["picture_ocr"] = text_score(ocr(big), truth)
        r["ok"], r["missed"] = verdict(r)
        print(f"{r['file']:60s} {'ok  ' if r['ok'] else 'MISS'} {','.join(r['missed'])}", file=sys.stderr)
    return {"rows": rows, "times": times, "when": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "cores": os.cpu_count()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--src", type=Path, default=ROOT / "bench" / ".sets")
    ap.add_argument("--only", help="the pictures whose file name holds this")
    ap.add_argument("--results", type=Path, default=ROOT / "docs" / "wild" / "results.json")
    ap.add_argument("--markdown", type=Path, help="write the report here (docs/WILD.md)")
    ap.add_argument("--report-only", action="store_true", help="write the report from the results file, run nothing")
    args = ap.parse_args()
    if args.report_only:
        res = json.loads(args.results.read_text())
    else:
        res = run(args.src, args.only)
        args.results.parent.mkdir(parents=True, exist_ok=True)
        args.results.write_text(json.dumps(res, indent=1))
    from wild_report import report

    text = report(res, args.src / "wild", ROOT / "docs" / "wild")
    if args.markdown:
        args.markdown.write_text(text)
    else:
        print(text)


if __name__ == "__main__":
    main()
