"""What the emoji model's inference solves cost and give (``ModelConfig.solve_colors``,
``solve_order``), side by side in one run, on pictures no model trained on.

Set: the 120 OpenMoji faces of bench/outlines.py (npm ``@iconify-json/openmoji``, ``make
bench-sets``), rendered at 64 px over white. Variants of the shipped emoji model, each on the
same pictures: the network's colours, the colours solved, the colours and the order solved.
Per variant: MSE at 1x of the model's own paths (``vectorize --no-refine --parts model``,
cairosvg render of the SVG), and median ms per picture one at a time and per picture in one
batch of all, one thread, the variants interleaved so that load falls on all alike.

Run: ``python bench/solves.py [--src bench/.sets] [--limit N] [--repeat R]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

from im2vec_cli.api import load_model  # noqa: E402
from im2vec_cli.infer import vectorize  # noqa: E402
from im2vec_cli.vector import rasterize_svg, to_svg  # noqa: E402
from outlines import emoji  # noqa: E402

VARIANTS = {"network colours": {"solve_colors": False, "solve_order": False},
            "colours solved": {"solve_colors": True, "solve_order": False},
            "colours and order solved": {"solve_colors": True, "solve_order": True}}
SIZE = 64


def pictures(src: Path, limit: int | None) -> list[torch.Tensor]:
    """The set's pictures ``(3, 64, 64)`` in [0, 1] over white."""
    return [torch.from_numpy(rasterize_svg(r["svg"], SIZE, SIZE).copy()).permute(2, 0, 1).float()
            for r in emoji(src, limit)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--src", default=str(ROOT / "bench" / ".sets"))
    ap.add_argument("--limit", type=int, default=120)
    ap.add_argument("--repeat", type=int, default=3, help="batched timings per variant (best kept)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    model, imgs = load_model("emoji", device="cpu"), pictures(Path(args.src), args.limit)
    base = model.config
    configs = {name: dataclasses.replace(base, **kw) for name, kw in VARIANTS.items()}
    single = {name: [] for name in VARIANTS}
    vectorize(model, imgs[:2])  # warm-up
    for img in imgs:  # one at a time, the variants interleaved
        for name, cfg in configs.items():
            model.config = cfg
            t = time.perf_counter()
            vectorize(model, [img])
            single[name].append(time.perf_counter() - t)
    print(f"{len(imgs)} OpenMoji faces at {SIZE} px, model emoji, torch {torch.__version__}, one thread")
    print("| variant | MSE@1x | ms / picture, one at a time (median) | ms / picture, one batch (best of "
          f"{args.repeat}) |\n|---|---|---|---|")
    for name, cfg in configs.items():
        model.config = cfg
        batch = []
        for _ in range(args.repeat):
            t = time.perf_counter()
            out = vectorize(model, imgs)
            batch.append(time.perf_counter() - t)
        mse = np.mean([float(((torch.from_numpy(rasterize_svg(to_svg(v, 3), SIZE, SIZE)).permute(2, 0, 1) - x) ** 2)
                              .mean()) for v, x in zip(out, imgs)])
        print(f"| {name} | {mse:.5f} | {1000 * statistics.median(single[name]):.0f} | "
              f"{1000 * min(batch) / len(imgs):.0f} |", flush=True)
    model.config = base


if __name__ == "__main__":
    main()
