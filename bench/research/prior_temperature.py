"""The sampling temperature a model's fitted prior stores, chosen on the validation split (issue 37).

A temperature T < 1 scales the standard deviations of the fitted latent prior: samples stay
nearer the modes of the training set's latents, so more of them look like the data (precision)
and fewer of its kinds are reached (recall): the truncation trick (Brock et al., ICLR 2019).
For each T, `sample`'s latents (``--samples``, seeded) are decoded and rendered as RESULTS.md's
sample-quality table does (``evaluate.sample_quality``) and scored by improved precision and
recall (k = 3) against as many validation-split images, in the feature net's space. The rule,
the same for every model and fixed before the test split is looked at: the T with the best F1 of
precision and recall. That T is then measured once on the test split beside T = 1. With
``--write`` it is stored in MODEL/latent_prior.json (``LatentPriorConfig.temperature``), which
`sample` then draws with unless told.

    python bench/research/prior_temperature.py --model models/fonts --data DATA/fonts [--write]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "src"))

from im2vec_cli.api import load_feature_net  # noqa: E402
from im2vec_cli.evaluate import eval_files, sample_quality  # noqa: E402
from im2vec_cli.files import atomic_write, load_image  # noqa: E402
from im2vec_cli.model.pretrained import from_pretrained  # noqa: E402
from im2vec_cli.model.prior import PRIOR_CONFIG  # noqa: E402

TEMPERATURES = (1.0, 0.9, 0.8, 0.7, 0.6, 0.5)


def f1(q: dict) -> float:
    p, r = q["precision"], q["recall"]
    return 0.0 if p + r == 0 else 2 * p * r / (p + r)


def scores(model, net, folder: Path, samples: int, t: float) -> dict:
    pictures = [load_image(f) for f in eval_files(folder, samples, 0)]
    return sample_quality(model, net, pictures, samples=samples, seed=0, prior="fitted", temperature=t)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", required=True, help="A model folder with a fitted prior.")
    ap.add_argument("--data", required=True, help="The dataset folder (its val/ and test/ splits).")
    ap.add_argument("--features", default=None, help="The feature net (default: models/features/<the model's name>).")
    ap.add_argument("--samples", type=int, default=1000)
    ap.add_argument("--temperatures", default=",".join(map(str, TEMPERATURES)), help="The ones to try, comma-separated.")
    ap.add_argument("--write", action="store_true", help="Store the chosen temperature in the model's prior.")
    args = ap.parse_args()
    folder, data = Path(args.model), Path(args.data)
    model = from_pretrained(folder)
    if model.latent_prior is None:
        sys.exit(f"{folder}: has no fitted prior")
    net = load_feature_net(args.features or ROOT / "models" / "features" / folder.name)
    print(f"{folder}: {args.samples} samples against as many images of {data / 'val'}, feature net {net.config}"[:200])
    print("T     precision recall  F1     p>=0.9  (validation)")
    val, temperatures = {}, [float(t) for t in args.temperatures.split(",")]
    for t in temperatures:
        t0 = time.perf_counter()
        q = val[t] = scores(model, net, data / "val", args.samples, t)
        print(f"{t:.2f}  {q['precision']:.3f}     {q['recall']:.3f}   {f1(q):.3f}  {q.get('confident', float('nan')):.3f}"
              f"   ({time.perf_counter() - t0:.0f} s)", flush=True)
    best = max(temperatures, key=lambda t: f1(val[t]))
    print(f"chosen T = {best} (best F1 on the validation split)")
    print("T     precision recall  F1     p>=0.9  (test)")
    for t in sorted({1.0, best}, reverse=True):
        q = scores(model, net, data / "test", args.samples, t)
        print(f"{t:.2f}  {q['precision']:.3f}     {q['recall']:.3f}   {f1(q):.3f}  {q.get('confident', float('nan')):.3f}",
              flush=True)
    if args.write:
        cfg = dataclasses.replace(model.latent_prior.config, temperature=best)
        atomic_write(folder / PRIOR_CONFIG, cfg.to_json())
        print(f"wrote temperature {best} into {folder / PRIOR_CONFIG}")


if __name__ == "__main__":
    main()
