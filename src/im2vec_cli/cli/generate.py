"""``sample`` and ``interpolate``: new graphics from the latent space."""

from __future__ import annotations

import click

from ..errors import Im2VecError
from ..options import GROW, MAX_GROW, MAX_TEMPERATURE, PARTS, PRIORS
from .app import EXIT_HELP, cli
from .batch import refuse_overwrite
from .options import Finite, load_model, model_options, nonempty, parse_segments, set_threads_for
from .streams import load_input_image, make_folder, write_output


@cli.command(epilog=EXIT_HELP)
@click.option("--n", "count", type=click.IntRange(1, 10000), default=16, show_default=True, help="How many samples.")
@click.option("-o", "--output", default="samples", show_default=True, callback=nonempty,
              help="Output folder (- with --n 1: the SVG to stdout).")
@click.option("--segments", default=None, help="Cubic segments per path (default: the model's).")
@click.option("--temperature", type=Finite(0, MAX_TEMPERATURE), default=None,
              help="Spread of the draws: the standard deviations of fitted and normal (0: the fitted prior's "
                   "component means), the step towards a neighbour (1: up to halfway; 0: the training latents "
                   "themselves); default: the one the prior stores, 1 for N(0, I).")
@click.option("--prior", type=click.Choice(PRIORS), default="auto", show_default=True,
              help="neighbours: between the latents of training pictures that look alike; fitted: the Gaussian "
                   "mixture fitted to them; normal: N(0, I); auto: the first of these the model stores.")
@click.option("--parts", type=click.Choice(PARTS), default="clean", show_default=True,
              help="clean: each shape as non-overlapping outer contours and holes; model: the model's own "
                   "(overlapping) paths.")
@model_options
def sample(count, output, segments, temperature, prior, parts, model_name, device, seed):
    """Decode N latents drawn from the prior (seeded) into SVGs, plus contact.png."""
    from .. import api

    check_set_output(output, count)
    set_threads_for(count)
    model = load_model(model_name, device, seed)
    k = parse_segments(segments)
    z = api.prior_latents(count, model, seed=seed, temperature=temperature, prior=prior)
    chunks = (api.decode(z[i : i + DECODE_CHUNK], model, segments=k, parts=parts) for i in range(0, count, DECODE_CHUNK))
    write_set(output, "sample", (im for chunk in chunks for im in chunk), count)


DECODE_CHUNK = 256  # latents decoded at once: memory stays flat in --n
CONTACT_MAX = 64  # images on a contact sheet (the first ones): its size stays bounded


def check_set_output(output: str, count: int) -> None:
    """Before any work: ``-o -`` (stdout) takes one SVG, so it is a usage error for more."""
    if output == "-" and count != 1:
        raise click.UsageError(f"-o -: stdout takes one SVG, and this writes {count}; give a folder")


def write_set(output: str, stem: str, images, count: int) -> None:
    """``OUT/<stem>_<i>.svg`` for each of ``count`` images, written as they come, and
    ``OUT/contact.png`` of the first ``CONTACT_MAX``; with ``-o -`` the one SVG to stdout."""
    from ..api import contact_sheet

    check_set_output(output, count)
    if output == "-":
        write_output("-", next(iter(images)).to_svg())
        return
    out = make_folder(output)
    width = len(str(count - 1))
    first = []
    for i, im in enumerate(images):
        write_output(out / f"{stem}_{i:0{width}d}.svg", im.to_svg())
        if i < CONTACT_MAX:
            first.append(im)
    write_output(out / "contact.png", contact_sheet(first))
    shown = f" (the first {CONTACT_MAX})" if count > CONTACT_MAX else ""
    click.echo(f"wrote {count} SVGs and contact.png{shown} to {out}/", err=True)


def latent_from(model, item: str):
    """A latent from `encode` (.npy, or a .json/.jsonl line) -> ``(D,)``; ``None`` for an image
    (read by ``load_input_image``)."""
    import json

    import numpy as np
    import torch

    low = item.lower()
    if low.endswith(".npy"):
        try:
            arr = np.load(item, allow_pickle=False)
        except (OSError, ValueError, EOFError) as exc:
            raise Im2VecError(f"{item}: not a readable .npy latent ({exc})") from None
        if not isinstance(arr, np.ndarray):  # an .npz archive under an .npy name
            arr.close()
            raise Im2VecError(f"{item}: an .npz archive, not one latent array (`im2vec encode --format npy` writes those)")
        if arr.dtype.kind not in "fiu":  # strings, objects, complex numbers: no latent (complex was cast silently)
            raise Im2VecError(f"{item}: holds {arr.dtype} values, where a latent holds real numbers")
        z = torch.from_numpy(arr.astype(np.float32)).view(-1)
    elif low.endswith((".json", ".jsonl")):
        try:
            with open(item) as f:
                z = torch.tensor(json.loads(f.readline())["latent"], dtype=torch.float32)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise Im2VecError(f"{item}: not a latent JSON line from `im2vec encode` ({exc})") from None
    else:
        return None
    if z.numel() != model.config.latent:
        raise Im2VecError(f"{item}: latent has {z.numel()} values, the model expects {model.config.latent}")
    if not torch.isfinite(z).all():
        raise Im2VecError(f"{item}: latent contains NaN or infinite values")
    return z


def endpoints(model, items: list[str], fit: bool, segments, grow: int = 0):
    """Each of ``items`` (images, or latents from `encode`) as a projection of one; the images
    are fitted together, in one batch (with at most ``grow`` parts grown on each: ``api.project``)."""
    from .. import api

    latents = [latent_from(model, item) for item in items]
    pictures = [load_input_image(item) for item, z in zip(items, latents) if z is None]
    fitted = iter(range(len(pictures)))
    proj = api.project(pictures, model, fit=fit, segments=segments, grow=grow) if pictures else None
    return [proj.take(next(fitted)) if z is None else z for z in latents]


MORPH_FRAMES = 24  # frames of morph.svg (at least): each shown for 1/8 s


@cli.command(epilog=EXIT_HELP)
@click.argument("a", callback=nonempty)
@click.argument("b", callback=nonempty)
@click.option("--steps", type=click.IntRange(0, 1000), default=4, show_default=True, help="In-between frames.")
@click.option("-o", "--output", default="interpolation", show_default=True, callback=nonempty, help="Output folder.")
@click.option("--segments", default=None, help="Cubic segments per path (default: the model's).")
@click.option("--animate", is_flag=True, help=f"Also write morph.svg: at least {MORPH_FRAMES} frames of the same "
              "interpolation, each as clean as the frames, played there and back (SMIL).")
@click.option("--parts", type=click.Choice(PARTS), default="clean", show_default=True,
              help="Frames: clean outer contours and holes, or the model's own paths.")
@click.option("--fit/--no-fit", default=True, show_default=True,
              help="Fit the model's paths to each image through the renderer (about 1 s), or keep the encoder's "
                   "guess (faster, coarser).")
@click.option("--grow", type=click.IntRange(0, MAX_GROW), default=GROW, show_default=True, metavar="N",
              help="With --fit: at most N pieces of each image grown where the model's fitted paths miss a part (an "
                   "eye, a mouth, a dot), matched across the two ends by position and colour and morphed with the "
                   "paths; 0: the model's paths alone.")
@model_options
def interpolate(a, b, steps, output, segments, animate, parts, fit, grow, model_name, device, seed):
    """Morph from A to B (images, or latents from `encode`): the model's paths of each, fitted
    to the image, interpolated.

    Writes frame_*.svg (endpoints included) and contact.png to the output folder.
    """
    from pathlib import Path

    from .. import api
    from ..api import flipbook_svg

    check_set_output(output, steps + 2)
    names = [f"frame_{i:0{len(str(steps + 1))}d}.svg" for i in range(steps + 2)] + ["contact.png", "morph.svg"]
    refuse_overwrite([Path(output) / n for n in names], [a, b])
    k = parse_segments(segments)
    if k == "auto":
        raise click.BadParameter("auto is for vectorize: every frame of a morph has one count", param_hint="--segments")
    set_threads_for(steps + 2)
    model = load_model(model_name, device, seed)
    za, zb = endpoints(model, [a, b], fit, k, grow)
    write_set(output, "frame", api.interpolate(za, zb, model, steps=steps, segments=k, parts=parts), steps + 2)
    if animate:
        many = api.interpolate(za, zb, model, steps=max(steps, MORPH_FRAMES - 2), segments=k, parts=parts)
        write_output(Path(output) / "morph.svg", flipbook_svg(many))
        click.echo(f"wrote {Path(output) / 'morph.svg'}", err=True)
