"""Command-line latency (issue "Inference commands"): `im2vec --help` and one `vectorize`
of a 64^2 glyph with the shipped default model, model load included, as a user runs them,
refined (`--effort fast`, the default for one image), with `--effort best` and with
`--no-refine`.

Run: ``python bench/cli.py`` (``make bench``).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXE = [sys.executable, "-m", "im2vec_cli"]


def wall(cmd: list[str], repeat: int = 5) -> list[float]:
    out = []
    for _ in range(repeat):
        t = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True, cwd=ROOT)
        out.append(time.perf_counter() - t)
    return out


def main():
    h = wall(EXE + ["--help"])
    print(f"im2vec --help: median {statistics.median(h) * 1e3:.0f} ms (min {min(h) * 1e3:.0f})")
    if not (ROOT / "models" / "fonts" / "config.json").exists():
        print("no shipped fonts model: vectorize not measured")
        return
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "g.svg")
        v = wall(EXE + ["vectorize", "examples/glyph_a.png", "-o", out, "--no-refine"])
        print(f"im2vec vectorize examples/glyph_a.png --no-refine (model load included): median "
              f"{statistics.median(v):.2f} s (min {min(v):.2f}, max {max(v):.2f}); target <= 2 s")
        r = wall(EXE + ["vectorize", "examples/glyph_a.png", "-o", out])
        print(f"im2vec vectorize examples/glyph_a.png (refined --effort fast, the default for one image): median "
              f"{statistics.median(r):.2f} s (min {min(r):.2f}, max {max(r):.2f}); target <= 2 s; refinement "
              f"itself: {statistics.median(r) - statistics.median(v):.2f} s")
        b = wall(EXE + ["vectorize", "examples/glyph_a.png", "-o", out, "--effort", "best"], repeat=3)
        print(f"im2vec vectorize examples/glyph_a.png --effort best: median {statistics.median(b):.2f} s "
              f"(min {min(b):.2f}); refinement itself: {statistics.median(b) - statistics.median(v):.2f} s")


if __name__ == "__main__":
    main()
