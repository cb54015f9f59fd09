"""``vectorize``, ``encode`` and ``render``: pictures to vectors, latents, and back to pixels."""

from __future__ import annotations

import click

from ..errors import Im2VecError
from .app import EXIT_HELP, cli, warn
from .batch import each, expand_inputs, plan_outputs, refuse_overwrite, run_batch
from .options import Finite, load_model, model_options, nonempty, parse_segments
from .streams import load_input_image, read_input, write_output

VECTORIZE_CHUNK = 32  # images per forward pass in batch mode (bounded memory, amortised model calls)
MAX_SVG_BYTES = 32 * 2**20  # `render` input: an SVG larger than this is refused while reading
EFFORTS = ["fast", "best"]  # refine.EFFORTS, spelled out so that `--help` does not import torch
PARTS = ["clean", "model"]  # refine.PARTS, likewise


@cli.command(epilog=EXIT_HELP)
@click.argument("inputs", nargs=-1, required=True, metavar="IMG...", callback=nonempty)
@click.option("-o", "--output", default="-", show_default=True, callback=nonempty,
              help="SVG file or - for one input; a folder for several inputs or a folder input.")
@click.option("--segments", default=None, help="Cubic segments per path (default: the model's).")
@click.option("--max-paths", "--paths", "max_paths", type=click.IntRange(1), default=None,
              help="Keep at most N paths (the largest).")
@click.option("--parts", type=click.Choice(PARTS), default="clean", show_default=True,
              help="With refinement: clean (each colour one path of outer contours and holes, no overlaps; from "
                   "the model's paths or the image's own regions, whichever fits better) or model (the model's own "
                   "paths, the same for every image of its class: for animation and the latent space).")
@click.option("--tolerance", type=Finite(0, min_open=True), default=None,
              help="With --parts clean: how far (input px) a curve may stray from the traced outline before a "
                   "segment is added; smaller is more exact, larger more compact. [0.5]")
@click.option("--colors", type=click.IntRange(1, 64), default=None,
              help="With --parts clean: palette size for a multi-colour image (1: two-tone). [auto, at most 16]")
@click.option("--quality", type=Finite(0, min_open=True), default=None,
              help="With --segments auto: the error one more segment must remove to be added (MSE on coverage) "
                   "[5e-4]; smaller is more exact, larger more compact.")
@click.option("--refine/--no-refine", default=None,
              help="Fit the paths to each input by gradient descent through the renderer (slower, more exact). "
                   "[on for a single image, off for several]")
@click.option("--effort", type=click.Choice(EFFORTS), default="fast", show_default=True,
              help="With refinement: fast (0.3-0.5 s per 64 px glyph on a CPU) or best (about 1 s, "
                   "half the pixel error).")
@click.option("--simplify", "simplify_px", type=Finite(0), default=None,
              help="Merge segments while the outline moves less than this many input pixels. [0.25 with --refine, else 0]")
@model_options
@click.pass_context
def vectorize(ctx, inputs, output, segments, quality, max_paths, parts, tolerance, colors, refine, effort, simplify_px,
              model_name, device, seed):
    """Vectorize images (PNG/JPG, any size) into SVGs of closed cubic paths.

    The SVG's viewBox is the input's pixel grid, so it overlays the input exactly.
    `-` reads one image from stdin; with -o - the SVG goes to stdout. A single image is
    refined against itself (--effort); several are vectorized in batches by the model alone
    unless --refine is given.
    """
    from .. import api

    k = parse_segments(segments)
    items = expand_inputs(inputs)
    single = len(items) == 1 and items[0][1] is None
    if not single and output == "-":
        raise click.UsageError("several inputs need -o DIR")
    dests, notes = plan_outputs(items, output, ".svg", single)
    model = load_model(model_name, device, seed)
    options = {"refine": single if refine is None else refine, "effort": effort, "segments": k, "quality": quality,
               "max_paths": max_paths, "simplify_px": simplify_px, "parts": parts, "tolerance": tolerance,
               "colors": colors}
    api.check_segments(model, k)  # before any file is read
    for note in notes:
        warn(note)
    where = dict(zip((item for item, _ in items), dests))

    def write(item, vec):
        try:
            write_output(where[item], vec.to_svg(), parents=not single)
            return item, None
        except Im2VecError as exc:
            return item, exc

    def work(group):
        loaded = []
        for item, _root in group:
            try:
                loaded.append((item, load_input_image(item)))
            except Im2VecError as exc:
                yield item, exc
        if options["refine"]:  # minutes per chunk: write each image as it is done
            for item, img in loaded:
                yield write(item, api.vectorize(img, model, **options))
        elif loaded:  # one batched forward pass per chunk
            for (item, _), vec in zip(loaded, api.vectorize([img for _, img in loaded], model, **options)):
                yield write(item, vec)

    run_batch(ctx, items, work, chunk=VECTORIZE_CHUNK)


@cli.command(epilog=EXIT_HELP)
@click.argument("inputs", nargs=-1, required=True, metavar="IMG...", callback=nonempty)
@click.option("-o", "--output", default="-", show_default=True, callback=nonempty,
              help="JSON lines file or -; a folder with --format npy.")
@click.option("--format", "fmt", type=click.Choice(["jsonl", "npy"]), default="jsonl", show_default=True)
@model_options
@click.pass_context
def encode(ctx, inputs, output, fmt, model_name, device, seed):
    """Encode images to latent vectors (the posterior mean): one JSON line per image, or .npy files."""
    import io
    import json

    import numpy as np

    from .. import api

    items = expand_inputs(inputs)
    if fmt == "npy" and output == "-":
        raise click.UsageError("--format npy needs -o DIR")
    model = load_model(model_name, device, seed)
    lines = []

    if fmt == "npy":
        dests, notes = plan_outputs([(i if i != "-" else "stdin.png", r) for i, r in items], output, ".npy", False)
        where = dict(zip((item for item, _ in items), dests))
        for note in notes:
            warn(note)
    else:
        refuse_overwrite([output], [item for item, _ in items])

    def work(item, root):
        z = api.encode(load_input_image(item), model)[0]  # (D,)
        if fmt == "npy":
            buf = io.BytesIO()
            np.save(buf, z)
            write_output(where[item], buf.getvalue(), parents=True)
        else:
            lines.append(json.dumps({"file": item, "model": getattr(model, "name", model_name),
                                     "latent": [round(v, 6) for v in z.tolist()]}))

    try:
        run_batch(ctx, items, each(work))
    finally:
        if fmt == "jsonl" and lines:
            write_output(output, "\n".join(lines) + "\n")


@cli.command(epilog=EXIT_HELP)
@click.argument("svg_file", metavar="SVG", callback=nonempty)
@click.option("-o", "--output", default="-", show_default=True, callback=nonempty, help="PNG file, or - for stdout.")
@click.option("--scale", type=Finite(min=0, min_open=True), default=1.0, show_default=True,
              help="Output pixels per viewBox unit.")
@click.option("--tau", type=Finite(min=0, min_open=True), default=0.15, show_default=True,
              help="Edge softness in output pixels.")
def render(svg_file, output, scale, tau):
    """Render an SVG of closed cubic paths to PNG with im2vec's own differentiable rasterizer."""
    from ..files import tensor_to_png
    from ..vector import from_svg, render_vector

    refuse_overwrite([output], [svg_file])
    image = from_svg(read_input(svg_file, limit=MAX_SVG_BYTES))
    write_output(output, tensor_to_png(render_vector(image, scale=scale, tau=tau)))
