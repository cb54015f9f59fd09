"""How much of the held-out pictures' outlines the decoded paths reach (issue 37, the outline loss).

The outline loss (``TrainConfig.outline``, ``src/im2vec_cli/training/outline.py``) is there to
bring a path to every part of the picture, where the renderer's gradient does not reach. This
measures that directly, for each model given, on a seeded subset of the test split: the
encoder's guess (``z = mu``) decoded at the model's segment count, and each picture's traced
outline (``outline_points``, 256 points) against points sampled on those paths:

- **cover**: the mean squared distance (px² of the model square) of an outline point to the
  nearest path point (the loss itself, on pictures no model trained on);
- **missed**: the share of outline points farther than ``--far`` px from every path;
- **pictures missing a part**: the share of pictures with more than 10% of their outline missed;
- **L2**: the per-picture MSE of the soft render (``tau`` 0.3, 2x2 supersampled) against the picture.

    python bench/research/outline_reach.py models/icons runs/icons-outline/model --data DATA/icons [--limit 500] [--markdown F]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch
from PIL import Image

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "src"))

from im2vec_cli.evaluate import eval_files  # noqa: E402
from im2vec_cli.model.pretrained import from_pretrained  # noqa: E402
from im2vec_cli.training.outline import outline_distances, trace_targets  # noqa: E402

BATCH = 64


def pictures(files: list[Path], size: int) -> torch.Tensor:
    """``(N, 3, S, S)`` in [0, 1]; the test pictures are already at the model's size."""
    out = []
    for f in files:
        im = Image.open(f).convert("RGB")
        if im.size != (size, size):
            raise SystemExit(f"{f}: {im.size}, not the model's {size} x {size}")
        out.append(torch.from_numpy(np.asarray(im, dtype=np.float32) / 255).permute(2, 0, 1))
    return torch.stack(out)


def measure(model_dir: str, x: torch.Tensor, targets: torch.Tensor, valid: torch.Tensor, far: float) -> dict:
    model = from_pretrained(model_dir).eval()
    size = model.config.image_size
    cover, missed, l2 = [], [], []
    with torch.no_grad():
        for i in range(0, len(x), BATCH):
            xb, tb = x[i:i + BATCH], targets[i:i + BATCH]
            dec = model.decode(model.encode(xb)[0], model.config.segments)
            d2 = outline_distances(dec.points, tb, size)  # (b, M) square pixels
            cover += d2.mean(1).tolist()
            missed += (d2 > far * far).float().mean(1).tolist()
            img = model.render(dec, tau=0.3, supersample=2)
            l2 += (img - xb).square().flatten(1).mean(1).tolist()
    keep = valid.numpy()
    cover_a, missed_a = np.array(cover)[keep], np.array(missed)[keep]
    return {"cover": cover_a.mean(), "missed": missed_a.mean(), "pictures": (missed_a > 0.1).mean(),
            "l2": float(np.mean(l2))}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("models", nargs="+")
    ap.add_argument("--data", required=True)
    ap.add_argument("--limit", type=int, default=500)
    ap.add_argument("--far", type=float, default=2.0, help="Pixels beyond which an outline point is missed.")
    ap.add_argument("--markdown", help="Also write the table to this file.")
    args = ap.parse_args()
    torch.manual_seed(0)
    size = from_pretrained(args.models[0]).config.image_size
    files = eval_files(args.data, args.limit, 0)
    x = pictures(files, size)
    outlines = trace_targets((x * 255).round().to(torch.uint8))  # x holds 8-bit levels: exact
    targets, valid = outlines.points, outlines.valid
    lines = [f"{len(files)} test pictures of {args.data} ({int(valid.sum())} with an outline), far = {args.far} px", "",
             "| model | cover (px²) | outline missed | pictures missing a part | L2 (soft render) |", "|---|---|---|---|---|"]
    print("\n".join(lines), flush=True)
    for m in args.models:
        r = measure(m, x, targets, valid, args.far)
        lines.append(f"| {m} | {r['cover']:.2f} | {100 * r['missed']:.1f}% | {100 * r['pictures']:.1f}% | {r['l2']:.4f} |")
        print(lines[-1], flush=True)
    if args.markdown:
        Path(args.markdown).write_text(f"# Outline reach (`python bench/{Path(__file__).name}`)\n\n" + "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
