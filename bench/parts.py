"""Small parts kept (issue 68): does a vectorization keep an emoji's eyes, mouth and letters, and
an icon's pieces and holes?

On the 64 test-split pictures of tests/assets/emoji_test and tests/assets/icons_test (never
trained on), each tool's SVG is rendered by cairosvg at the picture's size and judged against
the picture alone (no model, no trace of ours in the judge):

- **emoji, small parts**: the picture's colours are cut into at most ``COLORS`` by Pillow's
  median cut; a *part* is a 4-connected piece of one colour of ``PART_MIN``-``PART_MAX`` px whose
  colour (the median of the picture's pixels there) differs from its surround's (the median of a
  ``RING`` px ring around it) by at least ``CONTRAST`` (RGB distance on [0, 1]). It is *kept*
  when at least half of its core pixels (the part eroded by one pixel, where anything is left)
  are drawn nearer its own colour than its surround's.
- **icons, pieces and holes**: ink is darker than 0.5; pieces (8-connected) and holes
  (4-connected, not touching the border) of at least ``SPECK`` px are counted, and a picture
  counts when its render has as many of each.

Held out from any tuning of ``refine.grow``'s constants: ``--sets openmoji,fontawesome`` (bench/outlines.py's
OpenMoji faces and Font Awesome icons, no model trained on either), judged as emoji and icons.

    python bench/parts.py [--sets emoji,icons] [--tools model-guess,model-fitted,clean] [--limit N]
                          [--json out.json] [--markdown out.md] [--sheet out.png]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from im2vec_cli.files import load_picture  # noqa: E402
from im2vec_cli.vector import rasterize_svg, to_svg  # noqa: E402

COLORS = 12  # median-cut colours of an emoji: enough for its flat areas, few enough that edges merge into them
PART_MIN, PART_MAX = 6, 400  # px at 64 px: an eye, a mouth, a letter; not the face
RING = 2  # px around a part read as its surround
CONTRAST = 0.25  # RGB distance between a part and its surround for it to count
SPECK = 2  # px: icons' pieces and holes smaller than this are not counted

TOOLS = {  # name -> (vectorize options, what the table calls it)
    "model-guess": ({"parts": "model", "refine": False}, "`--parts model --no-refine` (the encoder's guess)"),
    "model-alone": ({"parts": "model", "grow": 0}, "`--parts model --grow 0` (the model's paths fitted alone)"),
    "model-fitted": ({"parts": "model"}, "`--parts model` (fitted, paths grown where they miss a part)"),
    "clean": ({}, "`vectorize` (the clean trace, polished)"),
}


def _dilate(mask: np.ndarray, r: int) -> np.ndarray:
    import cv2

    return cv2.dilate(mask.astype(np.uint8), np.ones((2 * r + 1, 2 * r + 1), np.uint8)).astype(bool)


def _erode(mask: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)


def emoji_parts(rgb: np.ndarray) -> list[dict]:
    """The small parts of an emoji ``(H, W, 3)`` in [0, 1]: ``{"mask", "core", "color", "around"}`` each."""
    import cv2

    img = Image.fromarray((rgb * 255).round().astype(np.uint8))
    idx = np.asarray(img.quantize(COLORS, method=Image.Quantize.MEDIANCUT))
    parts = []
    for c in np.unique(idx):
        n, lab, stats, _ = cv2.connectedComponentsWithStats((idx == c).astype(np.uint8), connectivity=4)
        for k in range(1, n):
            if not PART_MIN <= stats[k, cv2.CC_STAT_AREA] <= PART_MAX:
                continue
            mask = lab == k
            ring = _dilate(mask, RING) & ~mask
            if not ring.any():
                continue
            color, around = np.median(rgb[mask], 0), np.median(rgb[ring], 0)
            if np.linalg.norm(color - around) < CONTRAST:
                continue
            core = _erode(mask)
            parts.append({"mask": mask, "core": core if core.any() else mask, "color": color, "around": around})
    return parts


def part_kept(part: dict, out: np.ndarray) -> bool:
    """Whether ``out (H, W, 3)`` draws at least half of the part's core nearer its colour than its surround's."""
    px = out[part["core"]]
    own = np.linalg.norm(px - part["color"], axis=1)
    other = np.linalg.norm(px - part["around"], axis=1)
    return bool((own < other).mean() >= 0.5)


def pieces_and_holes(rgb: np.ndarray) -> tuple[int, int]:
    """Pieces (8-connected ink darker than 0.5) and holes (4-connected, off the border) of at least ``SPECK`` px."""
    import cv2

    ink = (rgb.mean(-1) < 0.5).astype(np.uint8)
    n, _, stats, _ = cv2.connectedComponentsWithStats(ink, connectivity=8)
    pieces = int((stats[1:, cv2.CC_STAT_AREA] >= SPECK).sum())
    m, lab, stats, _ = cv2.connectedComponentsWithStats(1 - ink, connectivity=4)
    border = set(np.unique(np.concatenate([lab[0], lab[-1], lab[:, 0], lab[:, -1]]))) - {0}
    holes = sum(1 for k in range(1, m) if k not in border and stats[k, cv2.CC_STAT_AREA] >= SPECK)
    return pieces, holes


def judge(name: str, rgb: np.ndarray, out: np.ndarray) -> dict:
    """One picture's verdict: emoji ``{"parts", "kept"}``; icons ``{"same": bool}``; and the MSE."""
    row = {"mse": float(((out - rgb) ** 2).mean())}
    if name == "emoji":
        parts = emoji_parts(rgb)
        row.update(parts=len(parts), kept=sum(part_kept(p, out) for p in parts))
    else:
        row.update(truth=pieces_and_holes(rgb), got=pieces_and_holes(out))
        row["same"] = row["truth"] == row["got"]
    return row


HELD_OUT = {"openmoji": "emoji", "fontawesome": "icons"}  # set -> the model and the judge it takes


def pictures_of(name: str, limit: int | None) -> tuple[list[str], list[np.ndarray]]:
    """A set's names and pictures ``(64, 64, 3)``: the test split of tests/assets (``emoji``, ``icons``, ...), or
    a held-out set of bench/outlines.py (``openmoji``: 120 OpenMoji faces; ``fontawesome``: 120 Font Awesome
    icons; ``make bench-sets`` fetches them), rendered at 64 px."""
    if name in HELD_OUT:
        sys.path.insert(0, str(ROOT / "bench"))
        import outlines

        rows = getattr(outlines, "emoji" if name == "openmoji" else "icons")(ROOT / "bench" / ".sets", None)[:limit]
        return [r["name"] for r in rows], [rasterize_svg(r["svg"], 64, 64) for r in rows]
    files = sorted((ROOT / "tests" / "assets" / f"{name}_test").glob("*.png"))[:limit]
    return [f.name for f in files], [load_picture(f) for f in files]


def run(name: str, tools: list[str], limit: int | None) -> dict:
    from im2vec_cli.vectorizing import load_model, vectorize_each

    files, pictures = pictures_of(name, limit)
    kind = HELD_OUT.get(name, name)
    model = load_model(kind)
    res = {}
    for tool in tools:
        t = time.perf_counter()
        vecs = vectorize_each(pictures, model, **TOOLS[tool][0])
        sec = time.perf_counter() - t
        rows = []
        for f, rgb, v in zip(files, pictures, vecs):
            h, w = rgb.shape[:2]
            svg = to_svg(v) if not isinstance(v, Exception) else None
            out = rasterize_svg(svg, w, h) if svg else np.ones_like(rgb)
            rows.append({"file": f, "svg": svg, **judge(kind, rgb, out)})
        res[tool] = {"rows": rows, "s": sec, "paths": float(np.mean([0 if isinstance(v, Exception) else len(v.shapes)
                                                                      for v in vecs]))}
        print(f"{name:6s} {tool:13s} {summary(kind, rows)}  {sec:.0f} s", flush=True)
    return res


def summary(name: str, rows: list[dict]) -> str:
    mse = np.mean([r["mse"] for r in rows])
    if name == "emoji":
        n, k = sum(r["parts"] for r in rows), sum(r["kept"] for r in rows)
        return f"small parts kept {k}/{n} ({100 * k / max(n, 1):.0f}%)  MSE {mse:.5f}"
    same = sum(r["same"] for r in rows)
    return f"same pieces and holes {same}/{len(rows)} ({100 * same / len(rows):.0f}%)  MSE {mse:.5f}"


def markdown(out: dict, command: str) -> str:
    """The table of every set and tool (``run``'s results)."""
    lines = [f"Written by `{command}` ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}); do not edit by hand. "
             "Definitions: bench/parts.py's docstring.", "",
             "| set | tool | kept | paths per picture | MSE at 1x | s for the set |", "|---|---|---|---|---|---|"]
    for name, res in out.items():
        for tool, r in res.items():
            lines.append(f"| {name} | {TOOLS[tool][1]} | {summary(HELD_OUT.get(name, name), r['rows']).split('  MSE')[0]} | "
                         f"{r['paths']:.1f} | {np.mean([x['mse'] for x in r['rows']]):.5f} | {r['s']:.0f} |")
    return "\n".join(lines) + "\n"


def sheet(name: str, res: dict, path: str, scale: int = 2, rows: int = 12) -> None:
    """The first ``rows`` pictures in a row each, then each tool's render: a contact sheet at ``scale``x."""
    files = [r["file"] for r in next(iter(res.values()))["rows"]][:rows]
    pics = pictures_of(name, len(files))[1]
    cols = [pics] + [[rasterize_svg(r["svg"], p.shape[1] * scale, p.shape[0] * scale) if r["svg"] else np.ones_like(p)
                      for r, p in zip(t["rows"], pics)] for t in res.values()]
    s = 64 * scale
    canvas = np.ones((s * len(files), s * len(cols), 3))
    for j, col in enumerate(cols):
        for i, im in enumerate(col):
            im = np.asarray(Image.fromarray((im * 255).astype(np.uint8)).resize((s, s), Image.NEAREST)) / 255
            canvas[i * s:(i + 1) * s, j * s:(j + 1) * s] = im
    Image.fromarray((canvas * 255).astype(np.uint8)).save(path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", default="emoji,icons")
    ap.add_argument("--tools", default=",".join(TOOLS))
    ap.add_argument("--limit", type=int, default=None)
    ap.add_argument("--json", default=None)
    ap.add_argument("--markdown", default=None)
    ap.add_argument("--sheet", default=None, help="a contact sheet per set: PATH with {set} in it")
    args = ap.parse_args()
    out = {}
    for name in args.sets.split(","):
        out[name] = run(name, args.tools.split(","), args.limit)
        if args.sheet:
            sheet(name, out[name], args.sheet.format(set=name))
    if args.markdown:
        Path(args.markdown).write_text(markdown(out, "python bench/parts.py " + " ".join(sys.argv[1:])))
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))


if __name__ == "__main__":
    main()
