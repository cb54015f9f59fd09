"""What a one-colour filled vector can reach on MNIST's grey strokes (issue 37, part of).

MNIST digits are grey-level scans: stroke cores are not all black and their edges fade over
2-3 px. A filled outline renders each pixel as the share of it inside the outline, so
it cannot follow a stroke's grey core; the ImageVAE, a raster decoder, can. To bound the
like-for-like ratio this measures, on the 64 test digits of tests/assets/mnist_test (and the
64 fonts glyphs as the control: pictures rendered from outlines):

- **smooth-outline oracle**: the filled region is the level set at 0.5 of the digit's 8x
  bicubic upsample (a smooth outline that follows the picture exactly, with as many segments
  as it needs), box-filtered back to the picture's pixels;
- **potrace** on an 8x bilinear upsample (its defaults), the SVG rendered by cairosvg;
- **im2vec vectorize** (the defaults: traced, refined through the renderer) and the shipped
  model's fitted projection (``eval --fit``), both rendered by cairosvg;

each as the mean per-image MSE on [0, 1] pixels and its ratio to our ImageVAE's on the same
images (models/baselines/<set>-imagevae).

    python bench/fill_bound.py [--markdown docs/results/fill-bound.md]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT))

from bench.vectorize import potrace  # noqa: E402

from im2vec_cli import api  # noqa: E402
from im2vec_cli.evaluate import reconstruction_l2  # noqa: E402
from im2vec_cli.model.pretrained import from_pretrained  # noqa: E402
from im2vec_cli.vector.cairo import rasterize_svg  # noqa: E402
from im2vec_cli.vector.svg import to_svg  # noqa: E402

UP = 8


def grey(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("L"), dtype=np.float64) / 255


def oracle(path: Path, level: float = 0.5) -> float:
    """MSE of the filled 0.5 level set of the 8x bicubic upsample, box-filtered back."""
    img = Image.open(path).convert("L")
    a = np.asarray(img, dtype=np.float64) / 255
    big = np.asarray(img.resize((img.width * UP, img.height * UP), Image.BICUBIC), dtype=np.float64) / 255
    cover = (big >= level).reshape(img.height, UP, img.width, UP).mean((1, 3))  # white share of each pixel
    return float(((cover - a) ** 2).mean())


def svg_mse(svg: str | bytes, path: Path) -> float:
    a = grey(path)
    return float(((rasterize_svg(svg, a.shape[1], a.shape[0]).mean(-1) - a) ** 2).mean())


def measure(name: str) -> dict:
    files = sorted((ROOT / "tests" / "assets" / f"{name}_test").glob("*.png"))
    row = {"set": name, "images": len(files)}
    row["oracle"] = float(np.mean([oracle(f) for f in files]))
    row["potrace"] = float(np.mean([svg_mse(potrace(f.read_bytes(), UP), f) for f in files]))
    t = time.perf_counter()
    out = api.vectorize([str(f) for f in files], name)
    row["vectorize"] = float(np.mean([svg_mse(to_svg(v), f) for v, f in zip(out, files)]))
    row["vectorize_s"] = time.perf_counter() - t
    row["fitted"] = reconstruction_l2(from_pretrained(name), files, fit=True, outlines=False)["recon_l2"]
    row["amortised"] = reconstruction_l2(from_pretrained(name), files, outlines=False)["recon_l2"]
    row["imagevae"] = reconstruction_l2(from_pretrained(f"baselines/{name}-imagevae"), files)["recon_l2"]
    return row


COLUMNS = (("oracle", "smooth-outline oracle"), ("potrace", f"potrace, {UP}x upsample"),
           ("vectorize", "`im2vec vectorize`"), ("fitted", "Im2Vec fitted"), ("amortised", "Im2Vec amortised"))


def markdown(rows: list[dict]) -> str:
    lines = [f"Written by `python bench/fill_bound.py` ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}). "
             "Mean per-image MSE on [0, 1] pixels (× our ImageVAE on the same images).", "",
             "| set | images | " + " | ".join(label for _, label in COLUMNS) + " | ImageVAE |",
             "|---|---|" + "---|" * (len(COLUMNS) + 1)]
    for r in rows:
        cells = [f"{r[k]:.5f} ({r[k] / r['imagevae']:.2f}×)" for k, _ in COLUMNS]
        lines.append(f"| {r['set']} | {r['images']} | " + " | ".join(cells) + f" | {r['imagevae']:.5f} |")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--markdown", default=None)
    args = ap.parse_args()
    rows = []
    for name in ("mnist", "fonts"):
        rows.append(measure(name))
        print("  ".join(f"{k} {v:.5f}" if isinstance(v, float) else f"{k} {v}" for k, v in rows[-1].items()), flush=True)
    text = markdown(rows)
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(text)


if __name__ == "__main__":
    main()
