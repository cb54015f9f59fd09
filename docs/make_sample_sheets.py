"""Contact sheets of `im2vec sample` for every shipped model, next to random test images.

For each model: 24 samples drawn by the tool from the Gaussian mixture fitted to the training
latents (`--prior fitted`, what `sample` gave before the neighbour prior), 24 from what `sample`
draws from by default (the neighbour prior where the model stores one), and 24 random images of
the model's test split (DATA/NAME/test when built, else tests/assets/NAME_test).

Usage: python docs/make_sample_sheets.py [--data DATA] [--out docs/samples] [--seed 0] [--only emoji,icons]
"""

from __future__ import annotations

import argparse
import random
import subprocess
import sys
import tempfile
from pathlib import Path

from PIL import Image, ImageDraw

from im2vec_cli.config import REPO_MODELS
from im2vec_cli.data.folder import list_images
from im2vec_cli.model.prior import NEIGHBOURS_CONFIG

N, COLUMNS, CELL = 24, 8, 96  # CELL: `sample`'s contact sheet cell
ROOT = Path(__file__).resolve().parents[1]
MODELS = ("fonts", "mnist", "emoji", "icons")


def sample_sheet(name: str, prior: str, seed: int, tmp: Path) -> Image.Image:
    out = tmp / f"{name}_{prior}"
    cmd = [sys.executable, "-m", "im2vec_cli", "sample", "--n", str(N), "--seed", str(seed), "--model", name,
           "--prior", prior, "-o", str(out)]
    subprocess.run(cmd, check=True, capture_output=True)
    return Image.open(out / "contact.png").convert("RGB")


def test_sheet(name: str, data: Path | None, seed: int) -> tuple[Image.Image, str]:
    folder = data / name / "test" if data and (data / name / "test").is_dir() else ROOT / "tests" / "assets" / f"{name}_test"
    files = random.Random(seed).sample(list_images(folder), N)
    sheet = Image.new("RGB", (COLUMNS * CELL, (N // COLUMNS) * CELL), "white")
    for i, f in enumerate(files):
        im = Image.open(f).convert("RGB")
        side = CELL / max(im.size)  # as `sample` draws: the image's frame fills the cell
        im = im.resize((round(im.width * side), round(im.height * side)), Image.LANCZOS)
        x, y = (i % COLUMNS) * CELL + (CELL - im.width) // 2, (i // COLUMNS) * CELL + (CELL - im.height) // 2
        sheet.paste(im, (x, y))
    return sheet, str(folder.relative_to(ROOT) if folder.is_relative_to(ROOT) else folder)


def labelled(panels: list[tuple[str, Image.Image]]) -> Image.Image:
    width = max(p.width for _, p in panels)
    height = sum(p.height + 22 for _, p in panels)
    out = Image.new("RGB", (width, height), "white")
    draw, y = ImageDraw.Draw(out), 0
    for title, p in panels:
        draw.text((4, y + 5), title, fill=(0, 0, 0))
        out.paste(p, (0, y + 22))
        draw.line([(0, y + 21), (width, y + 21)], fill=(200, 200, 200))
        y += p.height + 22
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "samples")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", default=None, help="comma-separated models (default: all four)")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name in MODELS:
            if not (REPO_MODELS / name).is_dir() or (args.only and name not in args.only.split(",")):
                continue
            real, where = test_sheet(name, args.data, args.seed)
            panels = [(f"{name}: im2vec sample --prior fitted (the Gaussian mixture)",
                       sample_sheet(name, "fitted", args.seed, Path(tmp)))]
            if (REPO_MODELS / name / NEIGHBOURS_CONFIG).is_file():
                panels.append((f"{name}: im2vec sample (by default, the neighbour prior)",
                               sample_sheet(name, "neighbours", args.seed, Path(tmp))))
            panels.append((f"{name}: random test images ({where})", real))
            labelled(panels).save(args.out / f"{name}.png")
            print(f"wrote {args.out / name}.png", flush=True)


if __name__ == "__main__":
    main()
