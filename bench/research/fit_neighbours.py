"""The neighbour prior of a shipped model: k chosen on the validation split, stored beside the weights.

`im2vec fit-prior` fits the Gaussian mixture and the neighbour prior (``model.prior.NeighbourPrior``)
together, encoding every training image for the mixture. A shipped model's mixture is already
fitted to its weights, so this encodes only the training images the neighbour prior keeps
(``model.prior.anchor_rows``, the same ones `fit-prior --seed S` keeps: the same prior), which
takes seconds instead of the mixture's minutes. For each k of ``--neighbours`` the samples are
scored as RESULTS.md's sample-quality table scores them (``evaluate.sample_quality``: improved
precision and recall, k = 3, in the feature net's space) against as many validation-split
images; the k with the best F1 is measured once on the test split beside the mixture, and with
``--write`` stored in MODEL (latent_neighbours.safetensors and .json). A set without a feature
net (emoji, icons) takes the first k given.

    python bench/research/fit_neighbours.py --model models/fonts --data DATA/fonts [--neighbours 1,3,8] [--write]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "src"))

from im2vec_cli.api import load_feature_net  # noqa: E402
from im2vec_cli.data.folder import load_folder, split_dir  # noqa: E402
from im2vec_cli.evaluate import eval_files, sample_quality  # noqa: E402
from im2vec_cli.files import load_image  # noqa: E402
from im2vec_cli.model.pretrained import from_pretrained  # noqa: E402
from im2vec_cli.model.prior import PRIOR_CONFIG, anchor_rows, fit_neighbours, posterior_means  # noqa: E402


def f1(q: dict) -> float:
    p, r = q["precision"], q["recall"]
    return 0.0 if p + r == 0 else 2 * p * r / (p + r)


def scores(model, net, folder: Path, samples: int, prior: str) -> dict:
    pictures = [load_image(f) for f in eval_files(folder, samples, 0)]
    return sample_quality(model, net, pictures, samples=samples, seed=0, prior=prior)


def show(tag: str, q: dict) -> str:
    return (f"{tag:14s} precision {q['precision']:.3f}  recall {q['recall']:.3f}  F1 {f1(q):.3f}  "
            f"p>=0.9 {q.get('confident', float('nan')):.3f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", required=True, help="A model folder (its mixture's seed is the subset's).")
    ap.add_argument("--data", required=True, help="The dataset folder (its train/, val/ and test/ splits).")
    ap.add_argument("--neighbours", default="8", help="The k to try, comma-separated (the first without a feature net).")
    ap.add_argument("--samples", type=int, default=1000)
    ap.add_argument("--write", action="store_true", help="Store the chosen neighbour prior in the model folder.")
    args = ap.parse_args()
    folder, data = Path(args.model), Path(args.data)
    model = from_pretrained(folder)
    seed = json.loads((folder / PRIOR_CONFIG).read_text())["seed"] if (folder / PRIOR_CONFIG).is_file() else 0
    t0 = time.perf_counter()
    train, _ = load_folder(split_dir(data, "train"), model.config.image_size, fit=model.config.fit)
    rows = anchor_rows(len(train), seed)
    mu = posterior_means(model, train[rows])
    print(f"{folder}: {len(rows)} of {len(train)} training images encoded ({time.perf_counter() - t0:.0f} s)", flush=True)
    feats = ROOT / "models" / "features" / folder.name
    net = load_feature_net(feats) if (feats / "config.json").is_file() else None
    fitted = {k: fit_neighbours(mu, k, seed=seed, data=str(data), images=len(train))
              for k in (int(k) for k in args.neighbours.split(","))}
    best = next(iter(fitted))
    if net is not None:
        val = {}
        for k, prior in fitted.items():
            model.neighbour_prior = prior
            val[k] = scores(model, net, data / "val", args.samples, "neighbours")
            print(show(f"k = {k} (val)", val[k]), flush=True)
        best = max(fitted, key=lambda k: (f1(val[k]), k))  # a tie: the larger k, more variety
        model.neighbour_prior = fitted[best]
        print(f"chosen k = {best} (best F1 on the validation split); test split once:")
        for prior in ("neighbours", "fitted"):
            print(show(f"{prior} (test)", scores(model, net, data / "test", args.samples, prior)), flush=True)
    if args.write:
        fitted[best].save(folder)
        print(f"wrote the neighbour prior (k = {best}) into {folder}")


if __name__ == "__main__":
    main()
