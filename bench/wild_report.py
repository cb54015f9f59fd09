"""docs/WILD.md and its contact sheets, from bench/wild.py's results file (docs/wild/results.json)."""

from __future__ import annotations

import statistics
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from wild import TOOLS, over_white

CELL = 160  # a sheet's cell: each picture and render fitted into CELL x CELL


def _med(vals: list[float]) -> str:
    return f"{statistics.median(vals):.4f}" if vals else "–"


def _table(rows: list[dict]) -> list[str]:
    out = ["| tool | MSE (median) | edge F1 (median) | OCR (mean, pages) | paths (median) | segments (median) | failed |",
           "|---|---|---|---|---|---|---|"]
    for tool in TOOLS:
        got = [r[tool] for r in rows if "error" not in r[tool]]
        ocrs = [g["ocr"] for g in got if "ocr" in g]
        cells = [_med([g["mse"] for g in got]), _med([g["f1"] for g in got]),
                 f"{statistics.mean(ocrs):.3f}" if ocrs else "–",
                 *(statistics.median([g[k] for g in got]) if got else "–" for k in ("paths", "segments")),
                 len(rows) - len(got)]
        out.append(f"| {tool} | " + " | ".join(map(str, cells)) + " |")
    return out


def _render(svg: str, w: int, h: int) -> np.ndarray | None:
    from im2vec_cli.vector import rasterize_svg

    return None if svg.startswith("error:") else rasterize_svg(svg, w, h)


def sheet(rows: list[dict], wild: Path, path: Path) -> None:
    """A row per picture: the picture, then each tool's SVG rendered at the same fitted size, with
    its MSE and edge F1 (and OCR) under it."""
    img = Image.new("RGB", (CELL * (1 + len(TOOLS)), (CELL + 28) * len(rows) + 14), "white")
    draw = ImageDraw.Draw(img)
    for j, name in enumerate(("picture (MSE, edge F1, OCR, paths under each)", *TOOLS)):
        draw.text((j * CELL + 2, 1), name if j else "picture", fill="black")
    for i, r in enumerate(rows):
        w, h = r["size"]
        k = CELL / max(w, h)
        fw, fh = max(1, round(w * k)), max(1, round(h * k))
        pic = Image.fromarray(np.round(over_white(wild / "pictures" / r["file"]) * 255).astype(np.uint8))
        tiles = [pic.resize((fw, fh), Image.LANCZOS if k < 1 else Image.NEAREST)]
        for tool in TOOLS:
            svg = (wild / "svg" / tool / (Path(r["file"]).stem + ".svg")).read_text()
            t = _render(svg, fw, fh)
            tiles.append(None if t is None else Image.fromarray(np.round(t * 255).astype(np.uint8)))
        top = 14 + i * (CELL + 28)
        for j, t in enumerate(tiles):
            if t is not None:
                img.paste(t, (j * CELL, top))
            if j == 0:
                label = f"{'(aside) ' if r['aside'] else ''}{r['file'][:24]}"
            else:
                s = r[TOOLS[j - 1]]
                label = ("error" if "error" in s else f"{s['mse']:.4f} F1 {s['f1']:.2f}" +
                         (f" OCR {s['ocr']:.2f}" if "ocr" in s else "") + f" {s['paths']}p")
            draw.text((j * CELL + 2, top + CELL + 2), label, fill="black")
            if j == 1 and not r["ok"]:
                draw.text((j * CELL + 2, top + CELL + 14), "miss: " + ",".join(r["missed"]), fill="red")
    img.save(path, quality=80, optimize=True)


def report(res: dict, wild: Path, out: Path) -> str:
    rows = res["rows"]
    out.mkdir(parents=True, exist_ok=True)
    kinds = sorted({r["kind"] for r in rows})
    lines = ["# The pictures nobody made for it", "",
             f"Written by `make bench-wild` ({res['when']}, {res['cores']} CPU cores) from docs/wild/results.json. "
             "How the pictures were chosen and scored: bench/wild_sets.py and bench/wild.py. "
             "im2vec, potrace and vtracer ran on the same files in one run.", ""]
    for name, part in (("tuned on", [r for r in rows if not r["aside"]]), ("kept aside", [r for r in rows if r["aside"]])):
        ok = sum(r["ok"] for r in part)
        lines.append(f"- **{name}**: {ok} of {len(part)} pictures at or above the better of potrace and vtracer "
                     f"on every metric ({100 * ok / max(1, len(part)):.0f}%)")
    ok = sum(r["ok"] for r in rows)
    lines += [f"- **all**: {ok} of {len(rows)} ({100 * ok / len(rows):.0f}%); written: "
              f"{sum('error' not in r['im2vec'] for r in rows)} of {len(rows)}",
              f"- one folder command: im2vec {res['times']['im2vec']:.1f} s (process start included); "
              f"potrace {res['times']['potrace']:.1f} s and vtracer {res['times']['vtracer']:.1f} s in process", ""]
    lines += ["## By kind", "", "| kind | pictures | at or above | missed on MSE | on edge F1 | on OCR |", "|---|---|---|---|---|---|"]
    for k in kinds:
        part = [r for r in rows if r["kind"] == k]
        lines.append(f"| {k} | {len(part)} | {sum(r['ok'] for r in part)} | "
                     + " | ".join(str(sum(m in r["missed"] for r in part)) for m in ("mse", "f1", "ocr")) + " |")
    for k in kinds:
        part = [r for r in rows if r["kind"] == k]
        sheet(part, wild, out / f"{k}.jpg")
        lines += ["", f"## {k}: {len(part)} pictures", "", *_table(part), "", f"![{k}](wild/{k}.jpg)"]
    read = [r for r in rows if "picture_ocr" in r]
    lines += ["", f"## Reading the text back: {len(read)} pictures with a true text", "",
              "tesseract on a 3x render (the picture itself resized the same way, for reference); "
              "the true texts are in bench/wild_text/.", "",
              "| picture | the picture | im2vec | potrace | vtracer |", "|---|---|---|---|---|"]
    for r in read:
        cells = ["error" if "error" in r[t] else f"{r[t]['ocr']:.2f}" for t in TOOLS]
        lines.append(f"| {r['file']} | {r['picture_ocr']:.2f} | " + " | ".join(cells) + " |")
    misses = [r for r in rows if not r["ok"]]
    lines += ["", f"## The misses: {len(misses)}", "", "| picture | kind | missed | im2vec MSE / F1 / OCR | better peer's |",
              "|---|---|---|---|---|"]
    for r in misses:
        me = r["im2vec"]
        peers = [r[t] for t in TOOLS[1:] if "error" not in r[t]]
        mine = "error" if "error" in me else f"{me['mse']:.4f} / {me['f1']:.3f} / {me.get('ocr', float('nan')):.2f}"
        best = (f"{min(p['mse'] for p in peers):.4f} / {max(p['f1'] for p in peers):.3f} / "
                f"{max(p.get('ocr', float('nan')) for p in peers):.2f}")
        lines.append(f"| {r['file']} | {r['kind']} | {', '.join(r['missed'])} | {mine} | {best} |")
    return "\n".join(lines) + "\n"
