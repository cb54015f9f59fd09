"""The Fonts dataset: one PNG per glyph plus its exact outline as SVG, split by family.

Layout of ``OUT``::

    OUT/{train,val,test}/<family-style>/<code>.png   black glyph on white, anti-aliased
    OUT/{train,val,test}/<family-style>/<code>.svg   exact outline, same pixel frame
    OUT/manifest.jsonl                               family, style, char, split, png, svg
    OUT/report.json                                  counts and skipped fonts with reasons

Glyphs are bbox-fitted (``glyphs.fit_outline``) and rendered from the outline with cairosvg.
"""

from __future__ import annotations

import json
import string
from collections.abc import Iterable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataError
from ..files import atomic_write, encode_png
from ..vector import rasterize_svg, to_svg
from .folder import hash_unit
from .glyphs import glyph_image, glyph_outline

DEFAULT_CHARS = string.ascii_lowercase + string.ascii_uppercase + string.digits
FONT_DIRS = ("/usr/share/fonts", "/usr/local/share/fonts")


def find_fonts(paths: Iterable[str | Path] | None = None) -> list[Path]:
    """Font files (.ttf, .otf) under ``paths`` (files or folders), or the system font folders."""
    roots = [Path(p) for p in (paths or FONT_DIRS)]
    out = []
    for root in roots:
        if root.is_file():
            out.append(root)
        elif root.is_dir():
            out += [p for p in root.rglob("*") if p.suffix.lower() in (".ttf", ".otf") and p.is_file()]
    return sorted(set(out))


def split_of(family: str, fractions=(0.8, 0.1, 0.1)) -> str:
    """Deterministic split by family name (hash), so no family is in two splits."""
    h = hash_unit(family.lower())
    if h < fractions[0]:
        return "train"
    return "val" if h < fractions[0] + fractions[1] else "test"


def _names(font) -> tuple[str, str]:
    name = font["name"]
    fam = name.getDebugName(16) or name.getDebugName(1) or "unknown"
    style = name.getDebugName(17) or name.getDebugName(2) or "Regular"
    return fam.strip(), style.strip()


def check_font(font, chars: str) -> str | None:
    """Why this font is unusable for the dataset, or ``None``.

    Rejects missing characters, pixel fonts (outlines made only of axis-aligned lines) and
    dingbat/symbol fonts (many characters with nearly the same outline, e.g. one box).
    """
    outlines = {}
    for c in chars:
        try:
            cs = glyph_outline(font, c)
        except DataError:
            return f"missing {c!r}"
        if not cs:
            return f"empty glyph {c!r}"
        outlines[c] = cs
    # pixel font: every point lies on an axis-aligned line with its neighbours (elevated lines only)
    axis = 0
    total = 0
    for cs in outlines.values():
        for c in cs:
            n = len(c)
            anchors = c[0::3]
            nxt = np.roll(anchors, -1, 0)
            straight = np.allclose(c[1::3], anchors + (nxt - anchors) / 3, atol=1e-6)
            aligned = np.all((np.abs(nxt - anchors) < 1e-6).any(-1))
            axis += int(straight and aligned)
            total += 1
            del n
    if total and axis / total > 0.95:
        return "pixel font (axis-aligned rectangles only)"
    # dingbats: fingerprint glyphs by a coarse raster of the outline's point cloud
    prints = set()
    for cs in outlines.values():
        pts = np.concatenate(cs)
        lo, hi = pts.min(0), pts.max(0)
        q = np.round((pts - lo) / np.maximum(hi - lo, 1e-9) * 7).astype(int)
        prints.add((len(cs), tuple(sorted(set(map(tuple, q))))))
    if len(prints) < 0.7 * len(outlines):
        return "symbol/dingbat font (glyphs nearly identical)"
    return None


@dataclass
class FontJob:
    path: str
    out: str
    chars: str
    size: int
    margin: float


def render_png(svg_text: str, size: int, supersample: int = 4) -> bytes:
    """Grey PNG of the outline: cairosvg at ``supersample`` x, box-filtered down, which gives
    exact area coverage (cairo's own 1x coverage is ~1% off on thin strokes)."""
    from PIL import Image

    big = rasterize_svg(svg_text, size * supersample, size * supersample).mean(-1)
    arr = big.reshape(size, supersample, size, supersample).mean((1, 3))
    return encode_png(Image.fromarray(np.round(arr * 255).astype(np.uint8), "L"))


def _process_font(job: FontJob) -> dict:
    from fontTools.ttLib import TTFont, TTLibError

    try:
        font = TTFont(job.path, fontNumber=0, lazy=True)
        family, style = _names(font)
        why = check_font(font, job.chars)
    except (TTLibError, OSError, KeyError, ValueError, AssertionError, DataError, Exception) as exc:  # noqa: B014
        return {"path": job.path, "skipped": f"unreadable ({type(exc).__name__}: {exc})"[:200]}
    if why:
        return {"path": job.path, "family": family, "skipped": why}
    split = split_of(family)
    slug = "".join(ch if ch.isalnum() else "_" for ch in f"{family}-{style}")
    folder = Path(job.out) / split / slug
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    try:
        for c in job.chars:
            svg = to_svg(glyph_image(font, c, size=job.size, margin=job.margin), decimals=3)
            stem = f"{ord(c):04x}"
            atomic_write(folder / f"{stem}.svg", svg)
            atomic_write(folder / f"{stem}.png", render_png(svg, job.size))
            rows.append({"family": family, "style": style, "char": c, "split": split,
                         "png": f"{split}/{slug}/{stem}.png", "svg": f"{split}/{slug}/{stem}.svg"})
    except Exception as exc:  # a font that breaks mid-way is reported, never fatal
        return {"path": job.path, "family": family, "skipped": f"failed while rendering ({exc})"[:200]}
    return {"path": job.path, "family": family, "style": style, "rows": rows}


def build_fonts(
    out: str | Path,
    fonts: Iterable[str | Path] | None = None,
    *,
    chars: str = DEFAULT_CHARS,
    size: int = 64,
    margin: float = 4.0,
    workers: int = 2,
    progress=None,
) -> dict:
    """Build the Fonts dataset into ``out``; returns the report (also written as report.json).

    Font files that share a family and style (the same font in two packages) are kept once.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = find_fonts(fonts)
    if not files:
        raise DataError("no font files found")
    jobs = [FontJob(str(p), str(out), chars, size, margin) for p in files]
    rows, skipped, seen = [], [], set()
    with ProcessPoolExecutor(max_workers=max(1, workers)) as pool:
        results = pool.map(_process_font, jobs, chunksize=4)
        for res in progress(results, total=len(jobs)) if progress else results:
            if "skipped" in res:
                skipped.append(res)
                continue
            key = (res["family"], res["style"])
            if key in seen:
                skipped.append({"path": res["path"], "family": res["family"], "skipped": "duplicate family/style"})
                continue
            seen.add(key)
            rows += res["rows"]
    atomic_write(out / "manifest.jsonl", "".join(json.dumps(r) + "\n" for r in rows))
    fams = {s: sorted({r["family"] for r in rows if r["split"] == s}) for s in ("train", "val", "test")}
    report = {
        "fonts_found": len(files), "fonts_used": len(seen), "glyphs": len(rows),
        "families": {s: len(v) for s, v in fams.items()},
        "skipped": skipped,
    }
    atomic_write(out / "report.json", json.dumps(report, indent=1))
    return report
