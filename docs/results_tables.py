"""docs/RESULTS.md's tables, written from the results of ``make results`` (docs/make_results.py).

Each ``_name`` gives one section's lines from the eval results (``label -> the eval's JSON``);
``write_markdown`` puts them together. Figures also published elsewhere (README, the cards) are
written by docs/figures.py from the same files.
"""

from __future__ import annotations

import json
import os
import platform
import sys
from datetime import datetime, timezone
from pathlib import Path

from figures import PAPER, fmt

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "results"


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import torch

    gpu = torch.cuda.get_device_name(0) if torch.cuda.is_available() else "no GPU"
    return f"{cpu}, {os.cpu_count()} cores, {gpu}, torch {torch.__version__}, Python {platform.python_version()}"


def training(model: str) -> str:
    """The training run's steps, wall time and hardware from the model's metrics.json."""
    try:
        t = json.loads((ROOT / model / "metrics.json").read_text()).get("training", {})
    except OSError:
        return "?"
    return f"{t.get('steps', '?'):,} steps, {t.get('wall', '?')} on {t.get('hardware', '?')}" if t else "?"


def write_markdown(results, sweeps, skipped, args, total_s, reused: int = 0, samples=None):
    now = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    L = [
        "# Results: the paper's tables, reproduced",
        "",
        f"Written by `make results` (`python docs/make_results.py`) on {now}; its evals took {total_s / 60:.0f} min on",
        f"{machine()}" + (f" ({reused} of them kept from an earlier run with `--reuse`, as the table at the end records)"
                          if reused else "") + ". Do not edit by hand: rerun the target.",
        "",
        "All figures are MSE on [0, 1] pixels (± standard error), measured on what a user gets: the",
        "SVG `im2vec vectorize` writes, rendered by cairosvg (the ImageVAE baseline: its raster output).",
        f"Test sets are seeded subsets of {args.limit} test-split images (fewer where the split is smaller);",
        "the test fonts families, the MNIST test digits and the emoji/icon test files were never trained on.",
        "Definitions: `src/im2vec_cli/evaluate.py`.",
    ]
    L += _table1(results) + _table2(results, args) + _samples(samples or {}) + _outlines(results) + (_sweeps(sweeps, args) if sweeps else [])
    L += _fonts_ablation()
    L += _phases()
    L += _provenance({**results, **{"sample quality: " + k: v for k, v in (samples or {}).items()}}, sweeps, skipped)
    (ROOT / "docs" / "RESULTS.md").write_text("\n".join(L) + "\n")
    print(f"wrote {ROOT / 'docs' / 'RESULTS.md'}", file=sys.stderr)


def _table1(results) -> list[str]:
    L = [
        "",
        "## Table 1: reconstruction L2 on the test split",
        "",
        "| dataset | model | recon L2 | paper (same model, its data) | images | paths / segments per image |",
        "|---|---|---|---|---|---|",
    ]
    for label, r in results.items():
        ds = label.split()[0]
        paper = PAPER.get(r["arch"], {}).get(ds)
        comp = f"{r['paths']:.2f} / {r['segments']:.1f}" if "paths" in r else "raster"
        kind = "ImageVAE (baseline)" if r["arch"] == "imagevae" else "Im2Vec, fitted (`--fit`)" if r.get("fit") else "Im2Vec"
        paper = None if r.get("fit") else paper
        L.append(f"| {ds} | {kind} | {fmt(r, 'recon_l2')} | {'–' if paper is None else f'{paper:.4f}'} | "
                 f"{r['images']} | {comp} |")
    return L + _ratios(results)


def _ratios(results) -> list[str]:
    """The like-for-like column: Im2Vec / ImageVAE on the same test images, beside the paper's."""
    L = ["", "Like for like: the ratio of the two models' figures on the same data (our datasets are not the",
         "paper's, so the absolute figures are not comparable with its; the ratio is). *Fitted*: the Im2Vec",
         "model's paths fitted to each test image through the renderer (`eval --fit`), against the ImageVAE's",
         "amortised output.", "",
         "| dataset | Im2Vec / ImageVAE (ours) | fitted / ImageVAE | paper (Im2Vec / ImageVAE) | at or below the paper's |",
         "|---|---|---|---|---|"]
    for ds in PAPER["im2vec"]:
        vec, fit, ras = results.get(ds), results.get(f"{ds} fitted"), results.get(f"{ds} ImageVAE")
        paper = PAPER["im2vec"][ds] / PAPER["imagevae"][ds]
        ours = vec["recon_l2"] / ras["recon_l2"] if vec and ras else None
        fitted = f"{fit['recon_l2'] / ras['recon_l2']:.2f}" if fit and ras else "–"
        shown = "–" if ours is None else f"{ours:.2f}"
        met = "–" if ours is None else ("yes" if ours <= round(paper, 1) else "no")
        L.append(f"| {ds} | {shown} | {fitted} | {paper:.2f} ({PAPER['im2vec'][ds]:.4f} / {PAPER['imagevae'][ds]:.4f}) "
                 f"| {met} |")
    ratios = ROOT / "docs" / "results" / "ratios.md"
    if ratios.is_file():  # every set, on the 64 test-split images kept in tests/assets (no dataset needed)
        L += ["", "The same ratios for every set on the 64 test-split images of `tests/assets/<set>_test`",
              "(`python bench/ratios.py --markdown docs/results/ratios.md`):", "",
              *ratios.read_text().splitlines()[2:]]
    bound = ROOT / "docs" / "results" / "fill-bound.md"
    if bound.is_file():  # what a filled outline can reach on grey-level digits (bench/fill_bound.py's docstring)
        L += ["", "MNIST's digits are grey-level scans, which a one-colour filled outline cannot follow inside a",
              "stroke. What filled outlines reach on the same 64 images, the fonts glyphs (rendered from outlines)",
              "as the control (`python bench/fill_bound.py --markdown docs/results/fill-bound.md`; the oracle is",
              "the 0.5 level set of the 8x bicubic upsample, filled and box-filtered back):", "",
              *bound.read_text().splitlines()[2:]]
    return L


def _table2(results, args) -> list[str]:
    L = [
        "",
        "## Table 2: generation and interpolation",
        "",
        f"Generation: {args.samples} latents from the prior (the *prior* column: what `sample` draws from,",
        "the model's neighbour prior where it stores one, else its fitted mixture, else N(0, I); rows of N(0, I)",
        "kept from a run before the fitted prior were decoded as",
        f"the model's even-odd paths), decoded; interpolation: {args.pairs} random",
        "training pairs, 4 evenly spaced interpolants each. Each image is scored by the MSE to its",
        "nearest training image at the model size (lower: closer to the data; a model that copies",
        "its training set scores 0, so this says little of quality: see *Sample quality* below).",
        "*Test images*: the test pictures scored the same way, how far new real pictures lie from the",
        "training set; samples well below it are near copies of training pictures (the neighbour prior",
        "draws between two training pictures' latents, so its samples are decoded mixtures of two close ones).",
        "",
        "| dataset | model | generation L2 | prior | test images | interpolation L2 | training images |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, r in results.items():
        if "generation_l2" in r:
            kind = "ImageVAE (baseline)" if r["arch"] == "imagevae" else "Im2Vec"
            held = fmt(r, "held_out_l2") if "held_out_l2" in r else "–"
            L.append(f"| {label.split()[0]} | {kind} | {fmt(r, 'generation_l2')} | {r.get('generation_prior', 'normal')} | "
                     f"{held} | {fmt(r, 'interpolation_l2')} | {r['train_images']:,} |")
    return L


def _samples(results) -> list[str]:
    """Improved precision and recall (k = 3) of the samples, with each prior the model has and N(0, I)."""
    rows = {k: r for k, r in results.items() if "precision" in r}
    if not rows:
        return []
    L = [
        "",
        "## Sample quality: improved precision and recall",
        "",
        "Kynkäänniemi et al. (NeurIPS 2019), k = 3: precision is the share of samples that fall in the",
        "k-NN balls of the test images, recall the share of test images in the balls of the samples,",
        "in the 128-d feature space of a small network trained in the project on the dataset's",
        "training split (`models/features/NAME`: a classifier of the 62 characters for fonts and of the 10",
        "digits for MNIST, each with one more class for blank, noise and pattern images; emoji and icons",
        "have no labels and no feature net yet, so no rows). 1,000 samples against",
        "1,000 test images (all the test split where smaller); *p ≥ 0.9*: the share of samples the",
        "classifier labels with probability at least 0.9 (of test images: last column). Samples are",
        "rendered by cairosvg from the SVGs `sample` writes; the ImageVAE's are its raster output.",
        "*neighbours*: between the latents of two training pictures that are near neighbours",
        "(`latent_neighbours.safetensors`, what `sample` uses where the model stores it); *fitted*: the Gaussian",
        "mixture fitted to the training set's latents (`latent_prior.safetensors`); *N(0, I)*: the VAE prior.",
        "",
        "| dataset | model | prior | precision | recall | p ≥ 0.9 | feature net (test) | p ≥ 0.9 of test images |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for label, r in rows.items():
        kind = "ImageVAE (baseline)" if r["arch"] == "imagevae" else "Im2Vec"
        acc = r.get("features_test_accuracy", -1)
        net = f"accuracy {acc:.3f}" if acc >= 0 else "autoencoder"
        runs = [(r["prior"], r)] + [(p, r[f"sample_quality_{p}"]) for p in ("neighbours", "fitted", "normal")
                                    if f"sample_quality_{p}" in r]
        for prior, q in runs:
            conf = f"{q['confident']:.3f}" if "confident" in q else "–"
            conf_test = f"{q['confident_test']:.3f}" if "confident_test" in q else "–"
            name = {"normal": "N(0, I)"}.get(prior, prior)
            L.append(f"| {label.split()[0]} | {kind} | {name} | {q['precision']:.3f} | {q['recall']:.3f} | {conf} | "
                     f"{net} | {conf_test} |")
    return L


def _outlines(results) -> list[str]:
    """Fonts only: their true outlines are the fonts' own (fontTools); the emoji and icon
    sources are coloured or stroked drawings that a dark-inside mask does not describe."""
    L = []
    # only sets whose every true outline was read: a few readable files of a set would not speak for it
    outl = {k: r for k, r in results.items()
            if k.startswith("fonts") and "outline_iou" in r and not r.get("outlines_unread")}
    if outl:
        L += [
            "",
            "## Against the true outlines",
            "",
            "IoU of the insides at 4x (cairosvg renders) and the symmetric Chamfer distance between the",
            "SVG outline and the font's own outline (fontTools), in input pixels. Only fonts: the emoji and",
            "icon sources are coloured drawings that a dark-inside mask does not describe. Amortised (one pass of the",
            "model, no refinement: the model's own paths, `vectorize --no-refine --parts model`). docs/VECTORIZE.md has the refined figures",
            "beside potrace and vtracer.",
            "",
            "| model | IoU at 4x | Chamfer (px) | glyphs |",
            "|---|---|---|---|",
        ]
        L += [f"| {k} | {fmt(r, 'outline_iou')} | {fmt(r, 'chamfer_px', 3)} | {r['outlines']} |" for k, r in outl.items()]
    return L


def _sweeps(sweeps, args) -> list[str]:
    L = []
    L += [
        "",
        "## Segments ablation (paper Fig. 5)",
        "",
        "Reconstruction L2 with every path decoded at k segments, k = 6…25, on a seeded subset of",
        f"{args.sweep_limit} test images. The models are trained once with k drawn per step, so one model",
        "decodes every k. *Deformation off at inference* decodes a model trained with the sample",
        "deformation on evenly spaced circle samples; the MNIST pair was trained with and without",
        "the deformation at the same short budget (the training-time ablation).",
        "",
    ]
    ks = [row["k"] for row in next(iter(sweeps.values()))["segments_sweep"]]
    cols = []
    for label, r in sweeps.items():
        cols.append((label, r["segments_sweep"]))
        if "segments_sweep_deform_off" in r:
            cols.append((label + ", deformation off at inference", r["segments_sweep_deform_off"]))
    L.append("| k | " + " | ".join(c[0] for c in cols) + " |")
    L.append("|---" * (len(cols) + 1) + "|")
    for i, k in enumerate(ks):
        L.append(f"| {k} | " + " | ".join(f"{c[1][i]['recon_l2']:.4f}" for c in cols) + " |")
    L.append("")
    for label, r in sweeps.items():
        png = f"results/sweep-{Path(r['model_dir']).name}.png"
        L.append(f"![{label}]({png})")
    if (OUT / "sweep-mnist.png").is_file():
        L.append("![MNIST: trained with and without deformation](results/sweep-mnist.png)")
    return L


def _fonts_ablation() -> list[str]:
    """The table of ``bench/research/fonts_ablation.py`` (docs/results/fonts-ablation.md), when it was run."""
    table = OUT / "fonts-ablation.md"
    if not table.is_file():
        return []
    return ["", "## Fonts: where the vector model's error comes from (one factor at a time)", "",
            "`python bench/research/fonts_ablation.py --steps 150 --markdown docs/results/fonts-ablation.md` (its docstring",
            "defines each row): the shipped `fonts` model's output with one stage after another replaced by a",
            "per-glyph optimisation through our renderer, scored like Table 1.", "", table.read_text().rstrip()]


def _phases() -> list[str]:
    """docs/results/phases.md: the training phases tried on a shipped model (``make train-<set>``,
    ``bench/ship_phase.py``), with the figures ``ship_phase`` printed for each."""
    table = OUT / "phases.md"
    if not table.is_file():
        return []
    return ["", *["#" + line if line.startswith("#") else line for line in table.read_text().rstrip().splitlines()]]


def _provenance(results, sweeps, skipped) -> list[str]:
    L = [
        "",
        "## How each figure was made",
        "",
        "| figure | command | eval wall time | model trained |",
        "|---|---|---|---|",
    ]
    for label, r in {**results, **{"ablation: " + k: v for k, v in sweeps.items()}}.items():
        L.append(f"| {label} | `{r['command']}` | {r['wall_s']:.0f} s | {training(r['model_dir'])} |")
    if skipped:
        L += ["", "Skipped (model or dataset missing on this machine): " + "; ".join(skipped) + "."]
    return L
