"""Any folder of SVGs (emoji, icons) rasterised with cairosvg onto white.

Layout: ``OUT/{train,val,test}/<name>.png`` with the source ``<name>.svg`` beside it as
ground truth, and ``OUT/manifest.jsonl``. ``colors`` quantises each image to at most that
many flat colours (the path-per-colour setting of the paper, sec. 3.4).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import DataError, InputError
from ..files import atomic_write, encode_png, read_regular
from ..vector import rasterize_svg
from ..vector.document import MAX_SVG_BYTES, read_svg_bytes
from .fonts import split_of


def _render(svg: bytes, size: int, colors: int | None) -> bytes:
    from PIL import Image

    rgb = rasterize_svg(svg, size, size)  # (size, size, 3) over white
    img = Image.fromarray(np.round(rgb * 255).astype(np.uint8), "RGB")
    if colors:
        img = img.quantize(colors=colors, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).convert("RGB")
    return encode_png(img)


def build_svg_set(out: str | Path, src: str | Path, *, size: int = 128, colors: int | None = None,
                  progress=None) -> dict:
    """Rasterise every ``*.svg`` under ``src``; unreadable SVGs are skipped and reported."""
    src, out = Path(src), Path(out)
    files = sorted(src.rglob("*.svg")) if src.is_dir() else []
    if not files:
        raise DataError(f"{src}: no .svg files found")
    names = {}  # output name -> source: checked whole before anything is written
    for f in files:
        name = str(f.relative_to(src).with_suffix("")).replace("/", "__")
        if name in names:
            raise DataError(f"{names[name]} and {f}: both would be written as {name}.svg; rename one")
        names[name] = f
    rows, skipped = [], []
    for name, f in progress(list(names.items())) if progress else names.items():
        split = split_of(name)
        try:  # a regular file (never waited on), bounded once inflated, its <use> fan-out bounded (check_bounds)
            data = read_svg_bytes(read_regular(f, MAX_SVG_BYTES, what="SVG file"), str(f))
            png = _render(data, size, colors)
        except InputError as exc:
            skipped.append({"svg": str(f), "reason": str(exc)[:200]})
            continue
        except Exception as exc:  # cairosvg raises many types on bad input; report, never crash
            skipped.append({"svg": str(f), "reason": f"{type(exc).__name__}: {exc}"[:200]})
            continue
        d = out / split
        d.mkdir(parents=True, exist_ok=True)
        atomic_write(d / f"{name}.png", png, durable=False)
        atomic_write(d / f"{name}.svg", data, durable=False)
        rows.append({"png": f"{split}/{name}.png", "svg": f"{split}/{name}.svg", "split": split})
    atomic_write(out / "manifest.jsonl", "".join(json.dumps(r) + "\n" for r in rows))
    report = {"images": len(rows), "skipped": skipped,
              "splits": {s: sum(r["split"] == s for r in rows) for s in ("train", "val", "test")}}
    atomic_write(out / "report.json", json.dumps(report, indent=1))
    return report
