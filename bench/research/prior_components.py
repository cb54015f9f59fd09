"""How many Gaussians the fitted latent prior gets, and how much they are shrunk, chosen on
the validation split (issue 37).

For the sets without a feature net to score samples by (emoji, icons: no class labels), the
mixture is judged as a density: it is fitted to the posterior means of the training images
(``model.prior.fit_prior``, as `im2vec fit-prior` fits it) and scored by the mean
log-likelihood of the validation images' posterior means, which it never saw. Too few
components spread the density over the gaps between kinds of picture (decoded: blends of
them); too many, each on a few dozen latents in 128 dimensions, fit the training latents and
score the held-out ones far lower unless their covariances are shrunk towards a sphere
(``shrink``: added to each diagonal, in units of the latents' mean variance). The rule, fixed
before the test split is looked at: the pair with the best validation log-likelihood; it is
then scored once on the test split beside the stored prior's, and written with
`im2vec fit-prior --components K --shrink S` when its samples, looked at and scored by their
generation L2 (RESULTS.md Table 2), are no worse than the stored prior's: a held-out likelihood
measures the density, not what its draws look like (on the feedback models' latents both sets'
picks were declined for that: models/emoji/README.md, models/icons/README.md).

    python bench/research/prior_components.py --model models/emoji --data DATA/emoji [--markdown F]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "src"))

from im2vec_cli.data.folder import load_folder, split_dir  # noqa: E402
from im2vec_cli.files import atomic_write  # noqa: E402
from im2vec_cli.model.pretrained import from_pretrained  # noqa: E402
from im2vec_cli.model.prior import fit_prior, posterior_means  # noqa: E402

COUNTS = (10, 20, 40, 60, 100, 160)
SHRINKS = (1e-4, 0.01, 0.03, 0.05, 0.1)


def latents(model, data: Path, split: str):
    """``(N, D)``: the posterior means of ``data``'s ``split`` images."""
    images, _ = load_folder(split_dir(data, split), model.config.image_size, fit=model.config.fit)
    return posterior_means(model, images)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", required=True, help="A model folder.")
    ap.add_argument("--data", required=True, help="The dataset folder (its train/, val/ and test/ splits).")
    ap.add_argument("--counts", default=",".join(map(str, COUNTS)), help="The component counts to try.")
    ap.add_argument("--shrinks", default=",".join(map(str, SHRINKS)), help="The shrinkages to try.")
    ap.add_argument("--seed", type=int, default=6)
    ap.add_argument("--markdown", default=None, help="Also write the table to this file.")
    args = ap.parse_args()
    model, data = from_pretrained(args.model).eval(), Path(args.data)
    t0 = time.perf_counter()
    train, val, test = (latents(model, data, s) for s in ("train", "val", "test"))
    lines = [f"# Latent prior components: {Path(args.model).name}", "",
             f"`python bench/research/prior_components.py --model {args.model} --data {args.data}` "
             f"({len(train)} training, {len(val)} validation, {len(test)} test latents; encoded in "
             f"{time.perf_counter() - t0:.0f} s). Mean log-likelihood in nats per latent "
             f"({train.shape[1]} dimensions); higher is better.", "",
             "| components | shrink | training | validation | fit (s) |", "|---|---|---|---|---|"]
    scores = {}
    for k in (int(c) for c in args.counts.split(",") if int(c) <= len(train) // 2):
        for shrink in (float(v) for v in args.shrinks.split(",")):
            t = time.perf_counter()
            prior = fit_prior(train, k, seed=args.seed, shrink=shrink)
            scores[k, shrink] = (prior, prior.log_prob(val).mean().item())
            lines.append(f"| {k} | {shrink:g} | {prior.log_prob(train).mean().item():.1f} | {scores[k, shrink][1]:.1f} | "
                         f"{time.perf_counter() - t:.0f} |")
            print(lines[-1], flush=True)
    best = max(scores, key=lambda key: scores[key][1])
    stored = model.latent_prior
    was = "" if stored is None else (f" against the stored prior's ({stored.config.components} components, shrink "
                                     f"{stored.config.shrink:g}) {stored.log_prob(test).mean().item():.1f}")
    lines += ["", f"Chosen on the validation split: **{best[0]} components, shrink {best[1]:g}**. On the test split, "
              f"once: {scores[best][0].log_prob(test).mean().item():.1f} nats{was}."]
    print("\n".join(lines[-1:]))
    if args.markdown:
        atomic_write(args.markdown, ("\n".join(lines) + "\n").encode())


if __name__ == "__main__":
    main()
