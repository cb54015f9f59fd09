"""Folders at full quality (issue "batched refinement"): one `im2vec vectorize DIR -o OUT`
over 1,000 held-out glyphs, refined in batches (the default), against refining one image at
a time, the model alone (`--no-refine`) and potrace, all in one run on the same files.

Set: a-z, A-Z, 0-9 of every face of GNU FreeFont and Lato (Debian fonts-freefont-ttf and
fonts-lato, neither in shared/data/font-packages.txt, so no shipped model trained on them),
an even spread of ``--n`` glyphs at 64 px, rendered like the Fonts dataset; the true outline
from fontTools, rendered at 4x, scores IoU@4x.

Rows (wall seconds as a user runs them: process start and model load included):

- ``im2vec DIR -o OUT``, the defaults for a folder this large: refined in chunks of 32, in
  one worker process per core (``-j``), eager kernels;
- ``--compile``: through ``torch.compile``, once with an empty compile cache (a fresh
  machine) and once with it warm (every later run);
- ``-j 1``: one process;
- one image at a time: ``refine()`` per glyph (model loaded) on an even subset of
  ``--sample`` glyphs, the per-glyph time scaled to the folder, with this code and, with
  ``--before DIR`` (a checkout of an older commit, e.g. ``git worktree add DIR 56b5f3e``), with
  that code (how a folder was refined before batching); their IoU@4x against the true
  outline is compared with the default run's on the same glyphs (target: within 0.002);
- ``--no-refine``: the model alone; its throughput after start-up subtracts one 1-glyph run;
- potrace over the same glyphs as PGM files.

Peak memory (max RSS, `/usr/bin/time`; with worker processes, of the parent alone: each
worker holds about as much again) of each command; ``--memory N`` adds a `--no-refine` run over
N files (10,000 for the issue's bound; refinement holds one chunk per worker at a time as well).

Run: ``make bench-folder`` or ``python bench/folder.py [--n 1000] [--sample 100] [--memory 10000]
[--before DIR] [--markdown docs/FOLDERS.md]``.
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

from im2vec_cli.data.fonts import render_png  # noqa: E402
from im2vec_cli.data.glyphs import glyph_image  # noqa: E402
from im2vec_cli.vector import rasterize_svg, to_svg  # noqa: E402
from outlines import CHARS, SIZE, UP, held_out_fonts  # noqa: E402
from vectorize import _pgm  # noqa: E402

FAMILIES = {"FreeSans", "FreeSerif", "FreeMono", "Lato"}
EXE = [sys.executable, "-m", "im2vec_cli"]


def glyph_set(n: int) -> tuple[list[dict], int]:
    faces = held_out_fonts(lambda face: face[0] in FAMILIES)
    rows = [{"name": f"{face[0]}-{face[1]}-{ord(c):04x}".replace(" ", "_"), "font": font, "char": c}
            for face, font in faces for c in CHARS]
    rows.sort(key=lambda r: r["name"])
    if len(rows) > n:
        rows = [rows[round(i * (len(rows) - 1) / (n - 1))] for i in range(n)]
    for r in rows:
        r["svg"] = to_svg(glyph_image(r.pop("font"), r.pop("char"), size=SIZE, margin=4.0), decimals=3)
        r["png"] = render_png(r["svg"], SIZE)
    return rows, len(faces)


def timed(cmd: list[str], env: dict | None = None) -> tuple[float, float]:
    """Wall seconds and peak memory (MiB) of one command."""
    t = time.perf_counter()
    r = subprocess.run(["/usr/bin/time", "-f", "%M", *cmd], capture_output=True, text=True,
                       env=None if env is None else {**os.environ, **env})
    wall = time.perf_counter() - t
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd[:6])} ... failed:\n{r.stderr[-2000:]}")
    return wall, int(r.stderr.strip().splitlines()[-1]) / 1024


def iou(svg: str, truth: np.ndarray) -> float:
    got = rasterize_svg(svg, SIZE * UP, SIZE * UP).mean(-1) < 0.5
    return float((got & truth).sum() / max((got | truth).sum(), 1))


def per_image(src: Path, pngs: Path, out: Path, model: str) -> float:
    """``refine()`` one glyph at a time with the code under ``src`` (in a fresh process, so that an
    older checkout can be measured): ms per glyph; the SVGs go to ``out``."""
    code = f"""
import sys, time
sys.path.insert(0, {str(src / "src")!r})
import torch
from pathlib import Path
from im2vec_cli.files import load_image
from im2vec_cli.model.pretrained import from_pretrained
from im2vec_cli.raster import set_compile
from im2vec_cli.refine import refine
from im2vec_cli.vector import to_svg
try:  # the fast effort, as this checkout names it
    from im2vec_cli.options import effort_plan
    fast = (effort_plan("fast"),)
except ImportError:  # before the run's Plan (issue 67)
    from im2vec_cli.refine import EFFORTS
    fast = ()
    refine = lambda m, im, r=refine: r(m, im, settings=EFFORTS["fast"])
set_compile(False)  # as the API runs one image
m = from_pretrained({model!r}, torch.device("cpu"))
files = sorted(Path({str(pngs)!r}).glob("*.png"))
imgs = [load_image(f) for f in files]
refine(m, imgs[0], *fast)  # warm-up
t = time.perf_counter()
svgs = [to_svg(refine(m, im, *fast)[0]) for im in imgs]
ms = 1e3 * (time.perf_counter() - t) / len(imgs)
for f, s in zip(files, svgs):
    (Path({str(out)!r}) / (f.stem + ".svg")).write_text(s)
print(ms)
"""
    out.mkdir(parents=True, exist_ok=True)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=src)
    if r.returncode != 0:
        raise SystemExit(f"one image at a time with {src} failed:\n{r.stderr[-2000:]}")
    return float(r.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--sample", type=int, default=100, help="glyphs refined one at a time")
    ap.add_argument("--memory", type=int, default=0, help="files in a --no-refine run for peak memory (0: skip)")
    ap.add_argument("--before", type=Path, default=None, help="a checkout of an older commit, refined one at a time too")
    ap.add_argument("--model", default="fonts")
    ap.add_argument("--markdown", default=None)
    args = ap.parse_args()
    rows, faces = glyph_set(args.n)
    n = len(rows)
    print(f"{n} glyphs of {faces} FreeFont/Lato faces at {SIZE} px", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        sample = [rows[round(i * (n - 1) / (args.sample - 1))] for i in range(args.sample)]
        src, pgm, few = _inputs(Path(tmp), rows, sample)
        start, res, default = folder_runs(Path(tmp), src, pgm, n, args.model, rows[0]["png"])
        truths = {r["name"]: rasterize_svg(r["svg"], SIZE * UP, SIZE * UP).mean(-1) < 0.5 for r in sample}
        res["iou"] = {"defaults": _mean_iou(default, truths)}
        for name, code in [("one image at a time", ROOT), ("one image at a time, before", args.before)]:
            if code is None:
                continue
            svgs = Path(tmp, name.replace(" ", "_").replace(",", ""))
            ms = per_image(code.resolve(), few, svgs, args.model)
            res[name] = {"s": ms * n / 1e3, "per_s": 1e3 / ms, "ms": ms}
            res["iou"][name] = _mean_iou(svgs, truths)
            print(f"{name}: {ms:.0f} ms per glyph, IoU@4x {res['iou'][name]:.4f}", flush=True)
        res["identical"] = sum((default / f"{k}.svg").read_text() == (Path(tmp, "one_image_at_a_time") / f"{k}.svg")
                               .read_text() for k in truths)
        if args.memory:
            big = Path(tmp, "big")
            big.mkdir()
            for i in range(args.memory):
                os.link(src / f"{rows[i % n]['name']}.png", big / f"{i:05d}.png")
            wall, mib = timed(EXE + ["vectorize", "--model", args.model, str(big), "-o", str(Path(tmp, "big_out")),
                                     "--no-refine"])
            res["memory"] = {"files": args.memory, "s": wall, "mib": mib}
    text = markdown(res, n, faces, start, args)
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(text)


def _inputs(tmp: Path, rows: list[dict], sample: list[dict]) -> tuple[Path, Path, Path]:
    """The glyphs as PNG (``png/``) and as PGM for potrace (``pgm/``), and the sample (``sample/``)."""
    src, pgm, few = tmp / "png", tmp / "pgm", tmp / "sample"
    for d in (src, pgm, few):
        d.mkdir()
    for r in rows:
        (src / f"{r['name']}.png").write_bytes(r["png"])
        (pgm / f"{r['name']}.pgm").write_bytes(_pgm(Image.open(io.BytesIO(r["png"]))))
    for r in sample:
        (few / f"{r['name']}.png").write_bytes(r["png"])
    return src, pgm, few


def folder_runs(tmp: Path, src: Path, pgm: Path, n: int, model: str, first: bytes) -> tuple[float, dict, Path]:
    """The folder run each way (and potrace's): (one glyph's --no-refine wall, the figures, the defaults' SVGs)."""
    one = tmp / "one"
    one.mkdir()
    (one / "a.png").write_bytes(first)
    base = ["vectorize", "--model", model]
    start, _ = timed(EXE + [*base, str(one / "a.png"), "-o", str(tmp / "a.svg"), "--no-refine"])
    cache = {"TORCHINDUCTOR_CACHE_DIR": str(tmp / "inductor")}  # empty at first: a fresh machine
    jobs = min(os.cpu_count() or 1, 8)
    # the defaults first and again last: this machine's speed drifts by 20% over minutes
    runs = {f"defaults (-j {jobs})": ([], None), "--compile, cold cache": (["--compile"], cache),
            "--compile, warm cache": (["--compile"], cache), "-j 1": (["-j", "1"], None),
            f"defaults (-j {jobs}), again": ([], None), "--no-refine": (["--no-refine"], None)}
    outs, res = {}, {}
    for name, (extra, env) in runs.items():
        out = tmp / f"out{len(outs)}"
        wall, mib = timed(EXE + [*base, str(src), "-o", str(out), *extra], env)
        outs[name] = out
        res[name] = {"s": wall, "mib": mib, "per_s": n / wall}
        print(f"{name}: {wall:.1f} s, {n / wall:.1f} glyphs/s, peak {mib:.0f} MiB", flush=True)
    res["--no-refine"]["after_start"] = n / max(res["--no-refine"]["s"] - start, 1e-9)
    wall, mib = timed(["potrace", "-s", *sorted(str(p) for p in pgm.glob("*.pgm"))])
    res["potrace"] = {"s": wall, "mib": mib, "per_s": n / wall}
    return start, res, outs[next(iter(runs))]


def _mean_iou(folder: Path, truths: dict) -> float:
    return float(np.mean([iou((folder / f"{k}.svg").read_text(), t) for k, t in truths.items()]))


def markdown(res: dict, n: int, faces: int, start: float, args) -> str:
    one = res["one image at a time"]
    before = res.get("one image at a time, before")
    lines = [f"# Folders: batched refinement ({n} held-out glyphs, one run)", "",
             f"`python bench/folder.py --n {args.n} --sample {args.sample} --memory {args.memory}"
             + (f" --before {args.before}" if args.before else "") + f"` on this machine ({os.cpu_count()} cores). "
             f"Glyphs: every face of GNU FreeFont and Lato ({faces} faces, packages no shipped model trained on), "
             "64 px. Wall time of one `im2vec vectorize DIR -o OUT` over the folder, process start and model load "
             f"included; one image at a time: `refine()` per glyph on an even subset of {args.sample}, scaled to "
             "the folder. Peak memory of the parent process (each worker holds about as much again).", "",
             "| run | wall s | glyphs/s | x one at a time (this code) | x one at a time (before) | peak MiB |",
             "|---|---|---|---|---|---|"]
    names = [k for k in res if isinstance(res[k], dict) and "per_s" in res[k]]
    for name in names:
        r = res[name]
        mib = f"{r['mib']:.0f}" if "mib" in r else "-"
        x_before = f"{r['per_s'] / before['per_s']:.2f}" if before else "-"
        lines.append(f"| {name} | {r['s']:.1f} | {r['per_s']:.1f} | {r['per_s'] / one['per_s']:.2f} | {x_before} | {mib} |")
    ious = ", ".join(f"{k} {v:.4f}" for k, v in res["iou"].items())
    lines += ["", f"- One image at a time: {one['ms']:.0f} ms per glyph with this code"
              + (f", {before['ms']:.0f} ms with the code before batching" if before else "") + ".",
              f"- Fidelity, IoU@4x against the true outline on the {args.sample} glyphs: {ious} (target: the "
              f"default within 0.002 of one at a time); {res['identical']} of {args.sample} SVGs byte-identical "
              "to one at a time.",
              f"- Model only after start-up ({start:.1f} s for one glyph): "
              f"{res['--no-refine']['after_start']:.0f} glyphs/s (target >= 500)."]
    if "memory" in res:
        m = res["memory"]
        lines.append(f"- {m['files']} files, --no-refine: {m['s']:.1f} s, peak {m['mib']:.0f} MiB (target <= 2048).")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
