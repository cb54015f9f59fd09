"""Past one machine (issue "Past one machine"): `vectorize DIR` on this host (its default worker
processes) against `vectorize DIR --engine ray` on a local Ray cluster of this host's CPUs, in
one run on the same held-out glyphs (GNU FreeFont and Lato: no shipped model trained on them),
wall seconds as a user runs them (process start, model loads and, for Ray, the cluster's start
and stop included), throughput after start-up, the cost per 1,000 pictures, and whether the two
engines wrote the same bytes.

    python bench/scale.py [--n 400] [--markdown docs/SCALE.md]   (make bench-scale)
"""

from __future__ import annotations

import argparse
import filecmp
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))

from folder import glyph_set  # noqa: E402

EXE = [sys.executable, "-m", "im2vec_cli"]


def timed(args: list[str]) -> float:
    t = time.perf_counter()
    r = subprocess.run(EXE + args, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(args[:4])} ... failed:\n{r.stderr[-2000:]}")
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=400, help="glyphs in the folder (a second run of 40 gives start-up)")
    ap.add_argument("--markdown", default=None)
    args = ap.parse_args()
    rows, faces = glyph_set(args.n)
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        for size, folder in ((args.n, d / "big"), (40, d / "small")):
            folder.mkdir()
            for r in rows[:size]:
                (folder / f"{r['name']}.png").write_bytes(r["png"])
        figures = {}
        for engine in ("local", "ray"):
            extra = ["--engine", "ray"] if engine == "ray" else []
            small = timed(["vectorize", str(d / "small"), "-o", str(d / f"{engine}-small"), *extra])
            big = timed(["vectorize", str(d / "big"), "-o", str(d / engine), *extra])
            per = (big - small) / (args.n - 40)  # seconds a picture once started
            figures[engine] = (small, big, per)
        names = sorted(p.name for p in (d / "local").iterdir())
        same = sum(filecmp.cmp(d / "local" / n, d / "ray" / n, shallow=False) for n in names)
    cores = os.cpu_count()
    lines = [f"{args.n} glyphs of {faces} GNU FreeFont / Lato faces at 64 px (none trained on), {cores} cores, one run.",
             "", "| engine | 40 pictures, s | " + f"{args.n} pictures, s | s a picture after start-up | "
             "min per 1,000 pictures | start-up, s |", "|---|---|---|---|---|---|"]
    for engine, (small, big, per) in figures.items():
        lines.append(f"| {engine} | {small:.1f} | {big:.1f} | {per:.3f} | {per * 1000 / 60:.1f} | "
                     f"{small - 40 * per:.1f} |")
    lines += ["", f"Ray / local, {args.n} pictures: {figures['ray'][1] / figures['local'][1]:.2f}x the wall time; "
              f"SVGs byte-identical: {same} of {len(names)}."]
    print("\n".join(lines))
    if args.markdown:
        text = Path(args.markdown).read_text() if Path(args.markdown).exists() else ""
        start, end = "<!-- bench/scale.py -->", "<!-- /bench/scale.py -->"
        block = f"{start}\n" + "\n".join(lines) + f"\n{end}"
        text = text[: text.index(start)] + block + text[text.index(end) + len(end):] if start in text else block + "\n"
        Path(args.markdown).write_text(text)


if __name__ == "__main__":
    main()
