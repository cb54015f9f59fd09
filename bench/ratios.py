"""Im2Vec against our ImageVAE, amortised and with the fitted projection (issue 37, part of).

For each set: the reconstruction L2 (``evaluate.reconstruction_l2``: the cairosvg render of the
SVG against each image, at its own size) of the shipped model's encoder guess (what `vectorize
--no-refine --parts model` writes), of its paths fitted to each image (``--fit``: ``project.project``, what
`interpolate` draws), and of the ImageVAE baseline (models/baselines/<set>-imagevae) on the
same images, with the ratios to the baseline. Images: the 64 test-split images of
tests/assets/<set>_test (never trained on), or with ``--data DATA`` a seeded subset of
``--limit`` images of DATA/<set>/test where that exists.

    python bench/ratios.py [--data DATA] [--limit 500] [--markdown docs/results/ratios.md]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from im2vec_cli.evaluate import eval_files, reconstruction_l2  # noqa: E402
from im2vec_cli.model.pretrained import from_pretrained  # noqa: E402

SETS = ("fonts", "mnist", "emoji", "icons")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=None)
    ap.add_argument("--limit", type=int, default=500)
    ap.add_argument("--markdown", default=None)
    args = ap.parse_args()
    rows = []
    for name in SETS:
        folder = Path(args.data, name, "test") if args.data else None
        if folder is None or not folder.is_dir():
            folder, limit = ROOT / "tests" / "assets" / f"{name}_test", None
        else:
            limit = args.limit
        files = eval_files(folder, limit, 0)
        row = {"set": name, "images": len(files), "where": str(folder.relative_to(ROOT) if folder.is_relative_to(ROOT)
                                                               else folder)}
        for key, model, fit in (("amortised", name, False), ("fitted", name, True),
                                ("imagevae", f"baselines/{name}-imagevae", False)):
            t = time.perf_counter()
            res = reconstruction_l2(from_pretrained(model), files, fit=fit, outlines=False)
            row[key], row[key + "_stderr"], row[key + "_s"] = res["recon_l2"], res["recon_l2_stderr"], time.perf_counter() - t
        print(f"{name:6s} {row['images']} images  amortised {row['amortised']:.5f} ({row['amortised'] / row['imagevae']:.2f}x)  "
              f"fitted {row['fitted']:.5f} ({row['fitted'] / row['imagevae']:.2f}x, {row['fitted_s']:.0f} s)  "
              f"ImageVAE {row['imagevae']:.5f}", flush=True)
        rows.append(row)
    if args.markdown:
        Path(args.markdown).write_text(markdown(rows))


def markdown(rows: list[dict]) -> str:
    lines = [f"Written by `python bench/ratios.py` ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}). "
             "Reconstruction L2 (cairosvg render of the SVG, at each image's size) ± standard error; ratio to our "
             "ImageVAE on the same images.", "",
             "| set | images | Im2Vec amortised | x ImageVAE | Im2Vec fitted (`eval --fit`) | x ImageVAE | s to fit | "
             "ImageVAE |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['set']} | {r['images']} ({r['where']}) | {r['amortised']:.5f} ± {r['amortised_stderr']:.5f} | "
                     f"{r['amortised'] / r['imagevae']:.2f} | {r['fitted']:.5f} ± {r['fitted_stderr']:.5f} | "
                     f"{r['fitted'] / r['imagevae']:.2f} | {r['fitted_s']:.0f} | {r['imagevae']:.5f} ± "
                     f"{r['imagevae_stderr']:.5f} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
