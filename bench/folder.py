"""Folders at full quality (issue "batched refinement"): one `im2vec vectorize DIR -o OUT`
over 1,000 held-out glyphs, refined in batches (the default), against refining one image at
a time, the model alone (`--no-refine`) and potrace, all in one run on the same files.

Set: a-z, A-Z, 0-9 of every face of GNU FreeFont and Lato (Debian fonts-freefont-ttf and
fonts-lato, neither in shared/data/font-packages.txt, so no shipped model trained on them),
an even spread of ``--n`` glyphs at 64 px, rendered like the Fonts dataset; the true outline
from fontTools, rendered at 4x, scores IoU@4x.

Rows (wall seconds as a user runs them: process start and model load included):

- ``im2vec`` (batched): the default, chunks of 32 refined together, `-j 1` and `-j 2`;
- one image at a time: ``refine()`` per glyph in this process (the model already loaded),
  on an even subset of ``--sample`` glyphs, the per-glyph time scaled to the folder; its
  IoU is compared with the batched run's on the same glyphs (target: within 0.002);
- ``--no-refine``: the model alone; its throughput after start-up subtracts one 1-glyph run;
- potrace over the same glyphs as PGM files.

Peak memory (max RSS, `/usr/bin/time`) of each command; ``--memory N`` adds a `--no-refine`
run over N files (10,000 for the issue's bound; refinement holds one chunk at a time as well).

Run: ``make bench-folder`` or ``python bench/folder.py [--n 1000] [--sample 100] [--memory 10000]
[--markdown docs/FOLDERS.md]``.
"""

from __future__ import annotations

import argparse
import io
import os
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

from im2vec_cli.data.fonts import _names, find_fonts, render_png  # noqa: E402
from im2vec_cli.data.glyphs import glyph_image  # noqa: E402
from im2vec_cli.vector import rasterize_svg, to_svg  # noqa: E402
from vectorize import _pgm  # noqa: E402

SIZE, UP = 64, 4
CHARS = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789"
FAMILIES = {"FreeSans", "FreeSerif", "FreeMono", "Lato"}
EXE = [sys.executable, "-m", "im2vec_cli"]
BEFORE_MS = 467  # per-image refinement before this change (commit 56b5f3e): docs/OUTLINES.md, 620 of these glyphs


def glyph_set(n: int) -> list[dict]:
    from fontTools.ttLib import TTFont

    used = set((ROOT.parent / "shared" / "data" / "font-packages.txt").read_text().split())
    rows, seen = [], set()
    for path in find_fonts():
        try:
            font = TTFont(str(path), fontNumber=0, lazy=True)
            face = _names(font)
        except Exception:  # noqa: BLE001 - unreadable fonts are not part of the set
            continue
        if face[0] not in FAMILIES or face in seen:
            continue
        seen.add(face)
        owner = subprocess.run(["dpkg", "-S", str(path)], capture_output=True, text=True).stdout.split(":")[0]
        if owner in used:
            raise SystemExit(f"{face} comes from {owner}, which the fonts training set uses")
        rows += [{"name": f"{face[0]}-{face[1]}-{ord(c):04x}".replace(" ", "_"), "font": font, "char": c}
                 for c in CHARS]
    rows.sort(key=lambda r: r["name"])
    if len(rows) > n:
        rows = [rows[round(i * (len(rows) - 1) / (n - 1))] for i in range(n)]
    for r in rows:
        r["svg"] = to_svg(glyph_image(r.pop("font"), r.pop("char"), size=SIZE, margin=4.0), decimals=3)
        r["png"] = render_png(r["svg"], SIZE)
    return rows, len(seen)


def timed(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak memory (MiB) of one command."""
    t = time.perf_counter()
    r = subprocess.run(["/usr/bin/time", "-f", "%M", *cmd], capture_output=True, text=True)
    wall = time.perf_counter() - t
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd[:6])} ... failed:\n{r.stderr[-2000:]}")
    return wall, int(r.stderr.strip().splitlines()[-1]) / 1024


def iou(svg: str, truth: np.ndarray) -> float:
    got = rasterize_svg(svg, SIZE * UP, SIZE * UP).mean(-1) < 0.5
    return float((got & truth).sum() / max((got | truth).sum(), 1))


def per_image(rows: list[dict], model: str) -> tuple[float, list[str]]:
    """``refine()`` one glyph at a time (what a folder cost before batching): ms per glyph, SVGs."""
    import torch

    from im2vec_cli.files import load_image
    from im2vec_cli.model.pretrained import from_pretrained
    from im2vec_cli.raster import set_compile
    from im2vec_cli.refine import EFFORTS, refine

    set_compile(False)  # as the API runs it
    m = from_pretrained(model, torch.device("cpu"))
    imgs = [load_image(io.BytesIO(r["png"])) for r in rows]
    refine(m, imgs[0], settings=EFFORTS["fast"])  # warm-up
    t = time.perf_counter()
    out = [to_svg(refine(m, im, settings=EFFORTS["fast"])[0]) for im in imgs]
    return 1e3 * (time.perf_counter() - t) / len(imgs), out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--sample", type=int, default=100, help="glyphs refined one at a time")
    ap.add_argument("--memory", type=int, default=0, help="files in a --no-refine run for peak memory (0: skip)")
    ap.add_argument("--model", default="fonts")
    ap.add_argument("--markdown", default=None)
    args = ap.parse_args()
    rows, faces = glyph_set(args.n)
    n = len(rows)
    print(f"{n} glyphs of {faces} FreeFont/Lato faces at {SIZE} px", flush=True)
    res = {}
    with tempfile.TemporaryDirectory() as tmp:
        src, pgm = Path(tmp, "png"), Path(tmp, "pgm")
        src.mkdir(), pgm.mkdir()
        for r in rows:
            (src / f"{r['name']}.png").write_bytes(r["png"])
            (pgm / f"{r['name']}.pgm").write_bytes(_pgm(Image.open(io.BytesIO(r["png"]))))
        one = Path(tmp, "one")
        one.mkdir()
        (one / "a.png").write_bytes(rows[0]["png"])
        base = ["vectorize", "--model", args.model]
        start, _ = timed(EXE + [*base, str(one / "a.png"), "-o", str(Path(tmp, "a.svg")), "--no-refine"])
        runs = {"im2vec (batched, default)": [], "im2vec -j 2": ["-j", "2"], "im2vec --no-refine": ["--no-refine"]}
        outs = {}
        for name, extra in runs.items():
            out = Path(tmp, name.replace(" ", "_"))
            wall, mib = timed(EXE + [*base, str(src), "-o", str(out), *extra])
            outs[name] = out
            res[name] = {"s": wall, "mib": mib, "per_s": n / wall}
            print(f"{name}: {wall:.1f} s, {n / wall:.1f} glyphs/s, peak {mib:.0f} MiB", flush=True)
        res["im2vec --no-refine"]["after_start"] = n / max(res["im2vec --no-refine"]["s"] - start, 1e-9)
        wall, mib = timed(["potrace", "-s", *sorted(str(p) for p in pgm.glob("*.pgm"))])
        res["potrace"] = {"s": wall, "mib": mib, "per_s": n / wall}
        sample = [rows[round(i * (n - 1) / (args.sample - 1))] for i in range(args.sample)]
        ms, svgs = per_image(sample, args.model)
        res["one image at a time"] = {"s": ms * n / 1e3, "per_s": 1e3 / ms, "ms": ms}
        truths = [rasterize_svg(r["svg"], SIZE * UP, SIZE * UP).mean(-1) < 0.5 for r in sample]
        batched = [(outs["im2vec (batched, default)"] / f"{r['name']}.svg").read_text() for r in sample]
        res["iou_one"] = float(np.mean([iou(s, t) for s, t in zip(svgs, truths)]))
        res["iou_batched"] = float(np.mean([iou(s, t) for s, t in zip(batched, truths)]))
        res["identical"] = sum(a == b for a, b in zip(svgs, batched))
        if args.memory:
            big = Path(tmp, "big")
            big.mkdir()
            for i in range(args.memory):
                os.link(src / f"{rows[i % n]['name']}.png", big / f"{i:05d}.png")
            wall, mib = timed(EXE + [*base, str(big), "-o", str(Path(tmp, "big_out")), "--no-refine"])
            res["memory"] = {"files": args.memory, "s": wall, "mib": mib}
    text = markdown(res, n, faces, start, args)
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(text)


def markdown(res: dict, n: int, faces: int, start: float, args) -> str:
    one = res["one image at a time"]
    lines = [f"# Folders: batched refinement ({n} held-out glyphs, one run)", "",
             f"`python bench/folder.py --n {args.n} --sample {args.sample} --memory {args.memory}` on this "
             f"machine ({os.cpu_count()} cores). Glyphs: every face of GNU FreeFont and Lato ({faces} faces, "
             "packages no shipped model trained on), 64 px. Wall time of one command over the folder, process "
             "start and model load included; one image at a time: `refine()` per glyph in-process on an even "
             f"subset of {args.sample}, scaled to the folder.", "",
             "| run | wall s | glyphs/s | x one image at a time | peak MiB |", "|---|---|---|---|---|"]
    for name in ["im2vec (batched, default)", "im2vec -j 2", "one image at a time", "im2vec --no-refine", "potrace"]:
        r = res[name]
        mib = f"{r['mib']:.0f}" if "mib" in r else "-"
        lines.append(f"| {name} | {r['s']:.1f} | {r['per_s']:.1f} | {r['per_s'] / one['per_s']:.2f} | {mib} |")
    best = max(res["im2vec (batched, default)"]["per_s"], res["im2vec -j 2"]["per_s"])
    lines += ["", f"- One image at a time: {one['ms']:.0f} ms per glyph. Before this change (commit 56b5f3e, "
              f"docs/OUTLINES.md, the same faces) it was {BEFORE_MS} ms: the best batched run is "
              f"{best * BEFORE_MS / 1e3:.1f}x that (target >= 10x).",
              f"- Fidelity on the {args.sample} glyphs: IoU@4x {res['iou_batched']:.4f} batched vs "
              f"{res['iou_one']:.4f} one at a time (difference {res['iou_batched'] - res['iou_one']:+.4f}, target "
              f"within 0.002); {res['identical']} of {args.sample} SVGs byte-identical.",
              f"- Model only after start-up ({start:.1f} s for one glyph): "
              f"{res['im2vec --no-refine']['after_start']:.0f} glyphs/s (target >= 500)."]
    if "memory" in res:
        m = res["memory"]
        lines.append(f"- {m['files']} files, --no-refine: {m['s']:.1f} s, peak {m['mib']:.0f} MiB (target <= 2048).")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
