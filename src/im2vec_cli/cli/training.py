"""``train``, ``train-aux`` and ``export``: models from images."""

from __future__ import annotations

import click

from ..config import DEFAULT_COMPONENTS, DEFAULT_NEIGHBOURS, DEFAULT_SHRINK
from ..errors import ConfigError, Im2VecError
from ..events import (
    AuxStep,
    DataLoaded,
    Encoding,
    Event,
    FeatureData,
    FeatureStep,
    FeatureTest,
    Measuring,
    NonFinite,
    NoPrior,
    PriorFitting,
    Resumed,
    Skipped,
    Teaching,
    TimeUp,
    Tracing,
    TrainStep,
    Validated,
)
from ..options import ARCHS, FITS, GROUPINGS
from .app import EXIT_HELP, cli, warn
from .options import SEED, Finite, device_option, load_model, model_options, nonempty


def _configs(config_file, model_opts: dict, train_opts: dict):
    """``--config`` JSON sections overridden by the command-line options (``None``: unset).

    Returns the two configs (validated) and the model and train options given on the command line or
    in the file (what a resumed run takes over its checkpoint's configs)."""
    from ..config import ModelConfig, TrainConfig, read_json

    sections = {}
    if config_file:
        sections = read_json(config_file)  # a regular file of at most 1 MiB, UTF-8 JSON: else one line
        if not isinstance(sections, dict):
            raise Im2VecError(f"{config_file}: expected a JSON object with 'model' and/or 'train' sections")
    for name in ("model", "train"):
        if not isinstance(sections.get(name, {}), dict):
            raise Im2VecError(f"{config_file}: the '{name}' section must be a JSON object")
    m = {**sections.get("model", {}), **{k: v for k, v in model_opts.items() if v is not None}}
    t = {**sections.get("train", {}), **{k: v for k, v in train_opts.items() if v is not None}}
    return ModelConfig.from_dict(m), TrainConfig.from_dict(t), m, t


def _say(e: Event) -> None:
    """Events of fit-prior and train-aux -> stderr lines."""
    match e:
        case Skipped(message=m):
            warn(f"skipped {m}")
        case Encoding(images=n):
            click.echo(f"encoding {n} images", err=True)
        case Measuring(images=n, paths=p):
            click.echo(f"measuring {n} images x {p} paths", err=True)
        case AuxStep(step=step, fit=fit, val_fit=val_fit):
            click.echo(f"step {step}: fit {fit:.4f}, held-out {val_fit:.4f}", err=True)


class _Progress:
    """Training events -> a progress bar (or plain lines when stderr is not a terminal) and warnings."""

    def __init__(self, device):
        self.device, self.bar = device, None

    def __call__(self, e: Event) -> None:
        from ..runtime import progress

        match e:
            case Skipped(message=m):
                warn(f"skipped {m}")
            case DataLoaded(train=n, val=v, steps=steps):
                click.echo(f"training on {n} images, validating on {v} ({self.device})", err=True)
                self.bar = progress(total=steps, desc="train", unit="step")
            case Resumed(step=step):
                self.bar.update(step)
            case Teaching(done=done, images=n) if done == n or done % 1024 == 0:
                click.echo(f"distillation: fitted the latents of {done}/{n} training images", err=True)
            case Tracing(done=done, images=n) if done == n:
                click.echo(f"outline loss: traced the outlines of {n} training images", err=True)
            case TimeUp(step=step, steps=steps):
                warn(f"--minutes ran out at step {step} of {steps}: the model is exported as it is (--resume goes on)")
            case TrainStep(step=step, figures=f, img_per_s=speed):
                self.bar.set_postfix(loss=f"{f['loss']:.4f}", img_s=f"{speed:.0f}", k=f["k"])
                self.bar.update(step - self.bar.n)
                if self.bar.disable:
                    click.echo(f"step {step} loss {f['loss']:.5f} img/s {speed:.0f}", err=True)
            case NonFinite(step=step, in_a_row=n):
                warn(f"step {step}: loss or gradient not finite, update skipped ({n} in a row)")
            case PriorFitting(images=n):
                click.echo(f"fitting the latent prior to the {n} training images' latents", err=True)
            case NoPrior(images=n, needed=needed):
                warn(f"no latent prior: {n} training image (it needs {needed}); `sample` draws from N(0, I)")
            case Validated(step=step, figures=f):
                click.echo(f"step {step}: val pyramid L2 {f['val_pyramid_l2']:.5f}, MSE {f['val_mse']:.5f}", err=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


@cli.command(epilog=EXIT_HELP)
@click.argument("data_dir", type=click.Path(file_okay=False), callback=nonempty)
@click.option("--out", "run_dir", default="runs/latest", show_default=True, callback=nonempty, help="Run directory.")
@click.option("--val", "val_dir", default=None, callback=nonempty, help="Validation folder (default: DATA_DIR/val, or a split).")
@click.option("--config", "config_file", default=None, type=click.Path(dir_okay=False),
              help="JSON with 'model' and/or 'train' sections (options below override it).")
@click.option("--arch", type=click.Choice(ARCHS),
              help="im2vec: the vector model; imagevae: the raster baseline of the paper (sec. 4). [im2vec]")
@click.option("--size", type=click.IntRange(8), help="Image size (power of two). [64]")
@click.option("--paths", type=click.IntRange(1), help="Paths per image. [4]")
@click.option("--latent", type=click.IntRange(1), help="Latent size. [128]")
@click.option("--grouping", type=click.Choice(GROUPINGS),
              help="evenodd: one even-odd shape of all paths (glyphs, digits); nonzero: one nonzero shape (overlaps stay filled; icons); layers: one coloured layer per path. [evenodd]")
@click.option("--batch", type=click.IntRange(1), help="Batch size. [64]")
@click.option("--steps", type=click.IntRange(1), help="Optimiser steps. [5000]")
@click.option("--epochs", type=Finite(0, min_open=True), help="Instead of --steps: passes over the data.")
@click.option("--lr", type=Finite(0, min_open=True), help="Peak learning rate. [5e-4]")
@click.option("--beta", type=Finite(0), help="KL weight. [1e-5]")
@click.option("--seed", type=SEED, help="Random seed. [0]")
@click.option("--workers", type=click.IntRange(1), help="Image loading threads. [2]")
@click.option("--resume", is_flag=True, help="Continue exactly from RUN/checkpoint.pt, with its configs (options given go over them).")
@click.option("--overwrite", is_flag=True, help="Start over in a RUN folder that holds a run (its run files are removed).")
@click.option("--init", "init_model", default=None, metavar="NAME|DIR",
              help="Fine-tune: start from this model's weights (a shipped name or a model folder), with a "
                   "fresh optimiser and schedule; the model options come from it, but --paths and --grouping "
                   "may change (new paths start as copies of the model's), and a config's palette may be "
                   "dropped (\"\": colours learned).")
@click.option("--minutes", type=Finite(0, min_open=True), default=None,
              help="A phase's time: past it, stop at the step reached, checkpoint and export (--resume goes on).")
@device_option
def train(data_dir, run_dir, val_dir, config_file, arch, size, paths, latent, grouping, batch, steps, epochs, lr,
          beta, seed, workers, resume, overwrite, init_model, minutes, device):
    """Train an Im2Vec model on a folder of images (PNG/JPG, searched recursively).

    A folder made by `im2vec data` (with train/ and val/) uses its own split. Unreadable
    images are skipped with a warning. Ctrl-C saves a checkpoint; --resume continues.
    The exported model is RUN/model (use it with --model RUN/model).
    """
    import os
    import signal

    from .. import api
    from ..options import GROWABLE, fixed_on_init
    from ..runtime import resolve_device

    model_cfg, train_cfg, model_given, train_given = _configs(
        config_file, {"arch": arch, "image_size": size, "paths": paths, "latent": latent, "grouping": grouping},
        {"batch": batch, "steps": steps, "lr": lr, "beta": beta, "seed": seed, "workers": workers})
    dev = resolve_device(device)
    start = None
    if init_model is not None:
        if resume:
            raise click.UsageError("--init starts a new run; --resume continues one: give one of them")
        start = load_model(init_model, "cpu", 0, raster_ok=True)
        fixed = fixed_on_init(model_given, start.config.to_dict())
        if fixed:
            raise click.UsageError("--init takes the model options from the model (but " + ", ".join(GROWABLE)
                                   + "); drop " + ", ".join(fixed))
        model_cfg = {k: v for k, v in model_given.items() if k in GROWABLE}
    elif resume:  # the checkpoint's configs, the options given over them
        model_cfg, train_cfg = model_given, train_given

    def _term(signum, frame):  # `kill` (and SIGINT-ignoring background jobs) checkpoint like Ctrl-C
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, _term)
    report = _Progress(dev)
    try:
        out = api.train(data_dir, run_dir, model_cfg, train_cfg, init=start, device=dev, val_dir=val_dir,
                        resume=resume, overwrite=overwrite, on_event=report, epochs=epochs, minutes=minutes)
    finally:
        report.close()
    if os.environ.get("RANK", "0") == "0":
        click.echo(f"model written to {out}", err=True)


@cli.command("train-aux", epilog=EXIT_HELP)
@click.argument("data_dir", type=click.Path(file_okay=False), callback=nonempty)
@click.option("-o", "--output", required=True, callback=nonempty,
              help="Folder for the model with its segment predictor (the input's own: updated in place, with --overwrite).")
@click.option("--overwrite", is_flag=True, help="Replace -o whole when it holds files (or update the model's own folder).")
@click.option("--images", type=click.IntRange(1), default=2048, show_default=True,
              help="Training images to measure (a seeded subset).")
@click.option("--steps", type=click.IntRange(1), default=3000, show_default=True, help="Optimiser steps of the fit.")
@model_options
def train_aux(data_dir, output, overwrite, images, steps, model_name, device, seed):
    """Train the segment-count predictor (paper sec. 3.3) of a trained model.

    Sweeps k for every path of DATA_DIR's images, fits loss(k) = a*exp(-b*k) + c per path
    code, and writes the model with the predictor to -o; then `--segments auto` works.
    """
    from .. import api

    model = load_model(model_name, device, seed)
    report = api.train_aux(data_dir, model, output, images=images, steps=steps, seed=seed, overwrite=overwrite,
                           on_event=_say)
    click.echo(f"held-out fit (log MSE) {report['val_fit_log_mse']:.4f}; model written to {output}", err=True)


@cli.command(epilog=EXIT_HELP)
@click.argument("run_dir", type=click.Path(file_okay=False), callback=nonempty)
@click.option("-o", "--output", required=True, callback=nonempty, help="Model folder to write (config.json + model.safetensors).")
@click.option("--half", is_flag=True, help="Store the weights in fp16 (half the size).")
@click.option("--overwrite", is_flag=True, help="Replace -o whole when it holds files (its old card and metrics go too).")
def export(run_dir, output, half, overwrite):
    """Export the model of a training run's latest checkpoint (e.g. after Ctrl-C)."""
    from .. import api

    out, step = api.export(run_dir, output, half=half, overwrite=overwrite)
    click.echo(f"exported step {step} to {out}", err=True)


@cli.command("fit-prior", epilog=EXIT_HELP)
@click.argument("data_dir", type=click.Path(file_okay=False), callback=nonempty)
@click.option("-o", "--output", required=True, callback=nonempty,
              help="Write the model with its prior to this folder (the model's own: its prior replaced, with --overwrite).")
@click.option("--overwrite", is_flag=True, help="Replace -o whole when it holds files (or the prior of the model's own folder).")
@click.option("--components", type=click.IntRange(1, 1000), default=None,
              help=f"Gaussians of the mixture (1: one full-covariance Gaussian). [{DEFAULT_COMPONENTS}, at most half "
                   "the images]")
@click.option("--shrink", type=click.FloatRange(0, 10), default=DEFAULT_SHRINK, show_default=True,
              help="Added to each Gaussian's variances, in units of the latents' mean variance: larger spreads each "
                   "over pictures like its own (see bench/research/prior_components.py).")
@click.option("--neighbours", type=click.IntRange(0, 64), default=None,
              help=f"Also keep the latents of (up to 4096 of) the images, each with this many nearest others, "
                   f"for `sample --prior neighbours` (0: none) [default: {DEFAULT_NEIGHBOURS}, fewer for a small set].")
@model_options
def fit_prior_cmd(data_dir, output, overwrite, components, shrink, neighbours, model_name, device, seed):
    """Fit the latent densities `sample` draws from to a trained model's training images.

    Encodes DATA_DIR's images (DATA_DIR/train when it exists) and fits a full-covariance
    Gaussian mixture to their posterior means (latent_prior.safetensors and .json); with
    --neighbours K it also keeps those latents, each with its K nearest
    (latent_neighbours.safetensors and .json: `sample` then draws between neighbours).
    Writes the model with them to -o. `train` fits both when it finishes.
    """
    from .. import api

    model = load_model(model_name, device, seed, raster_ok=True)
    try:
        prior = api.fit_prior(data_dir, model, output, components=components, seed=seed, overwrite=overwrite,
                              shrink=shrink, neighbours=neighbours, on_event=_say)
    except ConfigError as exc:  # the options checked against the data: --components, --neighbours
        raise click.UsageError(f"--{exc}") from None
    click.echo(f"mean log-likelihood {prior.config.log_likelihood:.1f} nats per image; "
               f"prior written to {output}", err=True)


@cli.command("train-features", epilog=EXIT_HELP)
@click.argument("data_dir", type=click.Path(file_okay=False), callback=nonempty)
@click.option("-o", "--output", required=True, callback=nonempty, help="Folder for the feature net.")
@click.option("--size", type=click.IntRange(32), default=64, show_default=True,
              help="Input size: the image size of the dataset's models (a multiple of 32).")
@click.option("--fit", type=click.Choice(FITS), default="resize", show_default=True,
              help="How smaller images are fitted to --size, as the dataset's models do (MNIST: pad).")
@click.option("--steps", type=click.IntRange(1), default=2000, show_default=True, help="Optimiser steps.")
@click.option("--seed", type=SEED, default=0, show_default=True, help="Random seed.")
def train_features(data_dir, output, size, fit, steps, seed):
    """Train the feature net of `eval --features` on a dataset's training split.

    A classifier when the folder layout names classes (MNIST: one folder per digit; fonts:
    one file per character in every family folder), with one more class for blank, noise and
    pattern images (outlier exposure), else an autoencoder. Its accuracy (or
    reconstruction MSE) on DATA_DIR/test is measured and stored in its config.
    """
    from .. import api

    def say(e: Event) -> None:
        match e:
            case Skipped(message=m):
                warn(f"skipped {m}")
            case FeatureData(images=n, classes=c, by=by):
                kind_of = f"a classifier of {c} classes (by {by} name)" if by else "an autoencoder"
                click.echo(f"training {kind_of} on {n} images", err=True)
            case FeatureStep(step=step, loss=loss) if step % 500 == 0:
                click.echo(f"step {step}: loss {loss:.4f}", err=True)
            case FeatureTest(images=n, accuracy=acc, mse=mse):
                what = f"accuracy {acc:.4f}" if acc is not None else f"reconstruction MSE {mse:.5f}"
                click.echo(f"test {what} on {n} images", err=True)

    api.train_features(data_dir, output, size=size, fit=fit, steps=steps, seed=seed, on_event=say)
    click.echo(f"feature net written to {output}", err=True)
