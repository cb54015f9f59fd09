"""``eval``: the paper's metrics for a model (Table 1, Table 2, Fig. 5)."""

from __future__ import annotations

import click

from ..options import PRIORS
from .app import EXIT_HELP, cli, warn
from .options import load_model, model_options, nonempty, parse_segments, parse_sweep
from .streams import write_output


def markdown_table(res: dict, with_train: bool) -> str:
    """The figures of an ``eval`` result as a markdown table (mean ± standard error, n)."""
    rows = [("reconstruction L2 (Table 1)", "recon_l2", "images")]
    if with_train:
        rows += [("generation L2 (Table 2)", "generation_l2", "generated"),
                 ("test images' L2 to the training set", "held_out_l2", "held_out"),
                 ("interpolation L2 (Table 2)", "interpolation_l2", "interpolants")]
    if "outline_iou" in res:
        rows += [("outline IoU at 4x", "outline_iou", "outlines"), ("Chamfer distance (px)", "chamfer_px", "outlines")]
    if "precision" in res:
        rows += [("sample precision (k = 3)", "precision", "samples"), ("sample recall (k = 3)", "recall", "samples")]
    lines = [f"| metric | {res['model']} | n |", "|---|---|---|"]
    lines += [f"| {label} | {res[key]:.4f}" + (f" ± {res[key + '_stderr']:.4f}" if key + "_stderr" in res else "")
              + f" | {res[n]} |" for label, key, n in rows]
    if "confident" in res:
        lines += [f"| samples labelled with p >= 0.9 | {res['confident']:.3f} | {res['samples']} |"]
    if "paths" in res:
        lines += [f"| paths / segments per image | {res['paths']:.2f} / {res['segments']:.1f} | {res['images']} |"]
    return "\n".join(lines) + "\n"


@cli.command("eval", epilog=EXIT_HELP)
@click.option("--data", "data_dir", required=True, callback=nonempty, help="Test images (DATA/test when it exists).")
@click.option("--limit", type=click.IntRange(1), default=None, help="Evaluate a seeded subset of N images.")
@click.option("--train-data", "train_dir", default=None, callback=nonempty,
              help="Training images (DATA/train when it exists): adds the generation and interpolation metrics.")
@click.option("--samples", type=click.IntRange(1), default=1000, show_default=True, help="Prior samples (generation).")
@click.option("--pairs", type=click.IntRange(1), default=250, show_default=True, help="Training pairs (interpolation).")
@click.option("--segments", default=None, help="Cubic segments per path (default: the model's).")
@click.option("--fit", is_flag=True, help="Reconstruct with the model's paths fitted to each image (what `interpolate` "
              "draws), not the encoder's guess (what `vectorize --no-refine --parts model` writes).")
@click.option("-o", "--output", default="-", show_default=True, callback=nonempty, help="JSON file or -.")
@click.option("--markdown", default=None, callback=nonempty, help="Also write the figures as a markdown table to this file.")
@click.option("--sweep", default=None, metavar="K1-K2",
              help="Segments ablation (paper Fig. 5): reconstruction L2 at every k in K1..K2, with the sample "
                   "deformation on and switched off at inference.")
@click.option("--plot", default=None, callback=nonempty, help="With --sweep: write the ablation plot to this PNG (needs matplotlib).")
@click.option("--features", "features_dir", default=None, callback=nonempty, metavar="DIR",
              help="A feature net from `train-features` (shipped: models/features/NAME): adds the precision and "
                   "recall of --samples prior samples against the test images in its feature space.")
@click.option("--prior", type=click.Choice(PRIORS), default="auto", show_default=True,
              help="Where the samples' latents come from (as `sample --prior`).")
@model_options
def eval_cmd(data_dir, limit, train_dir, samples, pairs, segments, fit, output, markdown, sweep, plot, features_dir,
             prior, model_name, device, seed):
    """The paper's metrics for a model, measured on the SVGs it writes (rendered by cairosvg).

    Reconstruction L2 (Table 1) on the test images, at each image's size; with --train-data,
    generation and interpolation L2 (Table 2): the MSE of decoded prior samples and of
    interpolants between training pairs to their nearest training image, at the model size,
    beside the same figure of the test images (how far new real pictures lie from them).
    Where the test images have their true outline beside them (NAME.svg, as `im2vec data
    fonts` writes), also IoU at 4x and the Chamfer distance; always paths and segments per image.
    With --features, sample quality: improved precision and recall (k = 3) of --samples
    samples against as many test images, in the feature net's space, and for a classifier
    the share of samples it labels with probability >= 0.9; with --prior auto, also of samples
    from the model's other priors and N(0, I), for comparison.
    An ImageVAE baseline (`train --arch imagevae`) is scored on its raster output, without
    the vector metrics.
    """
    import json

    from .. import api

    if plot and not sweep:
        raise click.UsageError("--plot needs --sweep")
    ks = parse_sweep(sweep) if sweep else None
    k = parse_segments(segments)
    if fit and k == "auto":
        raise click.UsageError("--fit fits paths of one segment count: --segments takes a number with it")
    model = load_model(model_name, device, seed, raster_ok=True)
    if ks and model.raster_output:
        raise click.UsageError("--sweep: the ImageVAE baseline has no segments")
    if fit and model.raster_output:
        raise click.UsageError("--fit: the ImageVAE baseline draws pixels, it has no paths to fit")
    note = api.test_split_note(data_dir)
    if note:
        warn(note)
    res = api.evaluate_model(model, data_dir, limit=limit, train_dir=train_dir, samples=samples, pairs=pairs,
                             segments=k, fit=fit, sweep=ks, features_dir=features_dir, prior=prior, seed=seed,
                             on_skip=lambda msg: warn(f"skipped {msg}"))
    res["model"] = getattr(model, "name", model_name)
    write_output(output, json.dumps(res, indent=1) + "\n")
    if plot:
        write_output(plot, api.sweep_figure(res))
    if markdown:
        write_output(markdown, markdown_table(res, bool(train_dir)))
