"""``vectorize``, ``encode`` and ``render``: pictures to vectors, latents, and back to pixels."""

from __future__ import annotations

import collections
import signal

import click

from ..errors import Im2VecError
from ..options import EFFORTS, MAX_GROW, MAX_SPECKLE, PARTS, PRESETS, VectorizeOptions
from .app import EXIT_HELP, cli, starting_up, warn
from .batch import (
    check_writable_folder,
    dedupe_inputs,
    expand_inputs,
    names_folder,
    plan_outputs,
    refuse_misnamed,
    refuse_overwrite,
    run_batch,
)
from .options import BYTES, Finite, lazy_model, load_model, model_options, nonempty, parse_segments, set_threads_for
from .streams import load_input_image, native_stderr_quiet, read_input, write_output

VECTORIZE_CHUNK = 32  # images per batch (one forward pass, one refinement batch): bounded memory, written as done
MAX_AUTO_JOBS = 8  # --jobs auto: at most this many (each may hold the model and about 0.5 GB)
PLAN_SAMPLE = 64  # --jobs auto: the pictures whose sizes are read to weigh the work (parallel.plan_jobs)


@cli.command(epilog=EXIT_HELP)
@click.argument("inputs", nargs=-1, required=True, metavar="IMG...", callback=nonempty)
@click.option("-o", "--output", default="-", show_default=True, callback=nonempty,
              help="SVG file or - for one input; a folder for several inputs or a folder input.")
@click.option("--segments", default=None, help="Cubic segments per path (default: the model's).")
@click.option("--max-paths", "--paths", "max_paths", type=click.IntRange(1), default=None,
              help="Keep at most N paths (the largest).")
@click.option("--parts", type=click.Choice(PARTS), default="clean", show_default=True,
              help="clean (each colour one path of outer contours and holes, no overlaps; with refinement from "
                   "the model's paths or the image's own regions, whichever fits better; with --no-refine the model's "
                   "guess with its seams mended) or model (the model's own overlapping paths, the same for every "
                   "image of its class: for animation and the latent space; refined, with paths grown on top where "
                   "they miss a part: --grow).")
@click.option("--grow", type=click.IntRange(0, MAX_GROW), default=None, metavar="N",
              help="With --parts model: add at most N paths on top of the model's where its fitted paths miss a part "
                   "of the picture (an eye, a dot, a hole), each one piece of the picture's own regions; 0: the "
                   "model's paths alone. [32]")
@click.option("--tolerance", type=Finite(0, min_open=True), default=None,
              help="With --parts clean: how far (input px) a curve may stray from the traced outline before a "
                   "segment is added; smaller is more exact, larger more compact. [0.5]")
@click.option("--colors", type=click.IntRange(1, 64), default=None,
              help="With --parts clean: palette size for a multi-colour image (1: two-tone). [auto, at most 16]")
@click.option("--quality", type=Finite(0, min_open=True), default=None,
              help="With --segments auto: the error one more segment must remove to be added (MSE on coverage) "
                   "[5e-4]; smaller is more exact, larger more compact.")
@click.option("--refine/--no-refine", default=True,
              help="Fit the paths to each input by gradient descent through the renderer; several inputs are "
                   "refined in batches. --no-refine: the model's guess alone (about 0.15 s a 64 px glyph once the "
                   "model is loaded, its passes included; with --parts model 0.1 s), for pictures like the model's "
                   "training set: scans, logos and other sets' pictures need refinement. [on]")
@click.option("--effort", type=click.Choice(EFFORTS), default="fast", show_default=True,
              help="With refinement: draft (clean outlines traced and fitted, not polished: the quickest), fast "
                   "(about 0.25 s for one 64 px glyph on 2 CPU cores, 40 ms each in a folder of them) or best "
                   "(about 1 s alone, half the pixel error).")
@click.option("--preset", type=click.Choice(PRESETS), default="auto", show_default=True,
              help="With --parts clean: what kind of picture it is. scan (ink on paper, photographed or scanned: "
                   "light flattened, noise smoothed, black ink made black), logo (flat colours), line (thin strokes), "
                   "pixel (pixel art: exact colours and pixel edges), photo (pieces of fine colour steps); auto: "
                   "the kind it looks like (-v shows it).")
@click.option("--filter-speckle", "speckle", type=click.IntRange(0, MAX_SPECKLE), default=None, metavar="PX",
              help="With --parts clean: drop pieces and holes smaller than PX x PX pixels from scans and line art "
                   "(0: keep all), and merge a photo's pieces smaller than that into their neighbours (its knob for "
                   "detail). [2, and 1 more per 256 px of the picture's longer side; at least 4 for a photo, but "
                   "a rendered one keeps its marks (text, dots) down to 2]")
@click.option("-v", "--verbose", is_flag=True, help="Per picture a line on stderr: the kind it was read as, paths, "
              "segments.")
@click.option("--simplify", "simplify_px", type=Finite(0), default=None,
              help="Merge segments while the outline moves less than this many input pixels. [0.25 with --refine, else 0]")
@click.option("--jobs", "-j", type=click.IntRange(1, 64), default=None,
              help="Worker processes for several inputs, each with its own copy of the model (on 2 cores, 2 refine "
                   f"about 1.5x faster than 1). [as many as finish soonest by the pictures' sizes, at most the free "
                   f"CPU cores and {MAX_AUTO_JOBS}; 1 on a GPU]")
@click.option("--compile/--no-compile", "compile_", default=False, show_default=True,
              help="Refine through torch.compile'd kernels: about 20 s to compile per image size the first time on a "
                   "machine (cached after); on 2 CPU cores it did not pay on a folder of 1000 glyphs (bench/folder.py).")
@click.option("--engine", type=click.Choice(["local", "ray"]), default="local", show_default=True,
              help="ray: the pictures are read by Ray Data and vectorized by actors that each load the model once, on "
                   "the cluster at --address or RAY_ADDRESS (else a local one on this host); -j sets the actors "
                   "(default: the cluster's CPUs, or its GPUs). The SVGs are the local run's, under the same names. "
                   "Needs pip install 'im2vec[ray]'.")
@click.option("--address", default=None, help="With --engine ray: the Ray cluster's address (ray://host:10001, auto).")
@click.option("--max-memory", type=BYTES, default=None, metavar="SIZE",
              help="Memory budget of the process (e.g. 1G, 800M): a picture too large to read within it is refused "
                   "before decoding, and a large one is vectorized at a smaller copy (at most 2048x2048; a two-colour one, a 1-bit scan, "
                   "up to 12.6 MP at 2G). [2G]")
@model_options
@click.pass_context
def vectorize(ctx, inputs, output, segments, quality, max_paths, parts, grow, tolerance, colors, refine, effort, preset,
              speckle, verbose, simplify_px, jobs, compile_, engine, address, max_memory, model_name, device, seed):
    """Vectorize images (PNG/JPG, any size) into SVGs of closed cubic paths.

    The SVG's viewBox is the input's pixel grid, so it overlays the input exactly.
    `-` reads one image from stdin; with -o - the SVG goes to stdout. Every image is refined
    against itself (--effort); several are refined in batches of images of one size, each SVG
    written when its batch is done.
    """
    k = parse_segments(segments)
    options = VectorizeOptions(refine=refine, effort=effort, segments=k, quality=quality, max_paths=max_paths,
                               grow=grow, simplify_px=simplify_px, parts=parts, tolerance=tolerance, colors=colors,
                               compile=compile_, max_memory=max_memory, preset=preset, speckle=speckle)
    for note in _ignored_options(ctx, options):
        warn(note)
    items = expand_inputs(inputs)
    single = len(items) == 1 and items[0][1] is None  # one input given: -o may name its file
    if not single and output == "-":
        raise click.UsageError("several inputs need -o DIR")
    if engine == "ray" and "-" in inputs:
        raise click.UsageError("--engine ray reads files: give files or folders, not - (stdin)")
    items, notes = dedupe_inputs(items)
    dests, more = plan_outputs(items, output, ".svg", single)
    notes += more
    if not single or names_folder(output):
        check_writable_folder(output)  # once, before the model loads: not one error per picture
    else:
        refuse_misnamed(output, "SVG")
    free = set_threads_for(len(items))
    with starting_up():  # (load_model pauses the collector too)
        from .. import api, runtime
    model = lazy_model(model_name, device, seed)  # loaded where a picture needs it: a traced one does not
    chunk, heavy = VECTORIZE_CHUNK, True
    if engine == "local" and len(items) > 1:
        jobs, chunk, heavy = _jobs(jobs, items, options, free, runtime.gpu_likely(device))
    api.check_segments(model, k)  # before any file is read
    for note in notes:
        warn(note)
    write = _writer(dict(zip((item for item, _ in items), dests)), single, verbose)
    if engine == "ray":
        with native_stderr_quiet():  # Ray's own processes' lines; ours still reach stderr
            run_batch(ctx, items, _on_ray(model_name, jobs, address, device, seed, options, write), chunk=len(items))
        return
    if jobs and jobs > 1 and len(items) > 1:
        threads = runtime.intra_op_threads(len(items), jobs, free)
        run_batch(ctx, items, _in_pool(model_name, jobs, threads, device, seed, options, write, chunk, heavy),
                  chunk=len(items))
    else:
        run_batch(ctx, items, _in_process(model, options, write, single=len(items) == 1), chunk=chunk)


def _jobs(jobs, items, options, free: int, gpu: bool) -> tuple[int, int, bool]:
    """``parallel.plan_workers``'s workers (``-j``, else as many as finish soonest by the sizes of up to
    ``PLAN_SAMPLE`` pictures; 1 on a GPU), pictures a chunk, and whether most pictures need the model."""
    from .. import api

    sides = [_picture_size(item) for item, _ in items[:PLAN_SAMPLE]]
    return api.plan_workers(options, sides, len(items), most=min(free, MAX_AUTO_JOBS), jobs=jobs, gpu=gpu,
                         chunk=VECTORIZE_CHUNK)


def _picture_size(item: str) -> tuple[int, int] | None:
    """A picture file's ``(W, H)`` from its header, or ``None`` (stdin, unreadable: found out later)."""
    from PIL import Image

    if item == "-":
        return None
    try:
        with Image.open(item) as im:
            return im.size
    except Exception:  # noqa: BLE001 - the picture's own error is reported when it is read
        return None


# options of the CLI alone -> (when it acts, given the parameters; when it does not, why); those of
# VectorizeOptions are noted by VectorizeOptions.idle, as the API warns of them
_APPLIES = {
    "address": (lambda p: p["engine"] == "ray", "it is the Ray cluster of --engine ray"),
    "verbose": (lambda p: p["engine"] == "local", "the Ray engine's actors describe no picture"),
}


def _writer(where: dict, single: bool, verbose: bool):
    """``write(item, result)`` -> ``(item, error or None)``: a picture's SVG (a vector image, or its
    text from the Ray engine) written to its planned output, or its failure, named."""

    def write(item, vec):
        if isinstance(vec, Exception):  # this picture's pipeline failed: the others go on
            return item, vec if str(vec).startswith(f"{item}: ") else Im2VecError(f"{item}: {vec}")
        try:
            write_output(where[item], vec if isinstance(vec, str) else vec.to_svg(), parents=not single)
            if verbose and not isinstance(vec, str):
                click.echo(describe_result(item, vec), err=True)
            return item, None
        except Im2VecError as exc:
            return item, exc

    return write


def _on_ray(model_name, jobs, address, device, seed, options, write):
    """``vectorize --engine ray``'s work: every input at once through ``rayengine.vectorize_on_ray``,
    each SVG written here as it comes back (the local run's names, atomically)."""
    import os

    from .. import api

    model_ref = os.path.abspath(model_name) if os.path.isdir(model_name) else model_name  # actors' cwd differs

    def work(group):
        by_path = {os.path.abspath(item): item for item, _ in group}
        for path, result in api.vectorize_on_ray(list(by_path), model_ref, options, jobs=jobs, address=address,
                                                       device=device, seed=seed):
            item = by_path[path]
            yield write(item, Im2VecError(str(result).replace(path, item)) if isinstance(result, Exception) else result)

    return work


def describe_result(item, vec) -> str:
    """One line on a vectorized picture: where from, the kind it was read as and what it measured,
    its paths and segments."""
    notes = vec.notes or {}
    figures = ", ".join(f"{k} {v}" for k, v in (notes.get("reading") or {}).items())
    kind = f"{notes['kind']} ({figures})" if figures else notes.get("kind", "model paths")
    return f"{item}: {kind}; {len(vec.shapes)} paths, {vec.num_segments} segments"


def _ignored_options(ctx: click.Context, options: VectorizeOptions) -> list[str]:
    """One warning for each option given on the command line that does nothing with the others."""
    from click.core import ParameterSource

    given = {n for n in ctx.params if ctx.get_parameter_source(n) == ParameterSource.COMMANDLINE}
    notes = ["--" + note for note in options.idle({"compile" if n == "compile_" else n for n in given})]
    return notes + [f"--{name} does nothing here: {why}" for name, (acts, why) in _APPLIES.items()
                    if name in given and not acts(ctx.params)]


ENCODE_CHUNK = 64  # images encoded (and fitted) in one batch


def _load(group, max_pixels: int | None = None):
    """-> the good ``(item, picture)`` of a group of inputs and the bad ``(item, error)``."""
    good, bad = [], []
    for item, _root in group:
        try:
            good.append((item, load_input_image(item, max_pixels)))
        except Im2VecError as exc:
            bad.append((item, exc))
    return good, bad


def _in_process(model, options, write, single: bool = False):
    """``vectorize``'s work on one chunk in this process: one forward pass, one refinement batch.
    ``single``: one picture, whose stages show as a progress bar on stderr (a terminal's) when
    it takes more than a second."""
    from .. import api
    from ..events import STAGES, Stage
    from ..runtime import progress

    def work(group):
        good, bad = _load(group, options.max_input_pixels())
        yield from bad
        if good:
            bar = progress(total=len(STAGES), desc=good[0][0], unit="stage", delay=1.0, leave=False,
                           disable=None if single else True)

            def hear(event):
                if isinstance(event, Stage):
                    bar.set_postfix_str(event.stage, refresh=False)
                    bar.update(1)

            try:
                got = api.vectorize_each([img for _, img in good], model, options, on_event=hear)
            finally:
                bar.close()
            for (item, _), vec in zip(good, got):
                yield write(item, vec)

    return work


def _in_pool(model_name, jobs, threads, device, seed, options, write, size=VECTORIZE_CHUNK, heavy=True):
    """``vectorize``'s work on all inputs at once, in chunks of ``size`` over ``jobs`` worker processes of
    ``threads`` threads (``heavy``: some pictures need the model, imported before the workers fork)."""
    from .. import api

    def work(group):
        names, bad = collections.deque(), []

        def chunks():
            for start in range(0, len(group), size):
                good, failed = _load(group[start : start + size], options.max_input_pixels())
                bad.extend(failed)
                for part in api.batch_groups(options, [img.shape for _, img in good]):  # (large ones alone)
                    names.append([good[i][0] for i in part])  # as (H, W, 3) arrays: tensors would travel through
                    yield [good[i][1] for i in part]  # shared memory and a file descriptor server that Ctrl-C stops

        def died(event):
            how = f" (killed by {signal.Signals(event.signal).name})" if event.signal in signal.valid_signals() else ""
            warn(f"a worker process died{how} with {event.pictures} pictures in hand: they are vectorized again, "
                 "a chunk at a time")

        for vecs in api.vectorize_chunks(chunks(), model_name, jobs=jobs, threads=threads, device=device,
                                         seed=seed, options=options, on_event=died, model=heavy):
            yield from bad
            bad.clear()
            for item, vec in zip(names.popleft(), vecs):
                yield write(item, vec)
        yield from bad

    return work


@cli.command(epilog=EXIT_HELP)
@click.argument("inputs", nargs=-1, required=True, metavar="IMG...", callback=nonempty)
@click.option("-o", "--output", default="-", show_default=True, callback=nonempty,
              help="JSON lines file or -; a folder with --format npy.")
@click.option("--format", "fmt", type=click.Choice(["jsonl", "npy"]), default="jsonl", show_default=True)
@click.option("--fit/--no-fit", default=True, show_default=True,
              help="Fit each latent to its image through the renderer, or keep the encoder's guess (the posterior "
                   "mean: faster, coarser).")
@model_options
@click.pass_context
def encode(ctx, inputs, output, fmt, fit, model_name, device, seed):
    """Encode images to latent vectors: one JSON line per image, or .npy files. Images are
    encoded ENCODE_CHUNK at a time, in one batch."""
    import io
    import json

    import numpy as np

    from .. import api

    items, notes = dedupe_inputs(expand_inputs(inputs))
    if fmt == "npy" and output == "-":
        raise click.UsageError("--format npy needs -o DIR (or -o FILE.npy for one image)")
    if fmt == "npy":  # one image and -o z.npy: that file (it made a folder z.npy); else a folder of them
        single = len(inputs) == 1 and items[0][1] is None and output.lower().endswith(".npy") and not names_folder(output)
        dests, more = plan_outputs([(i if i != "-" else "stdin.png", r) for i, r in items], output, ".npy", single)
        where = dict(zip((item for item, _ in items), dests))
        notes += more
        if not single:
            check_writable_folder(output)
    else:
        refuse_overwrite([output], [item for item, _ in items])
    for note in notes:
        warn(note)
    set_threads_for(len(items))
    model = load_model(model_name, device, seed)
    lines = []

    def write(item, z):
        if fmt == "npy":
            buf = io.BytesIO()
            np.save(buf, z)
            write_output(where[item], buf.getvalue(), parents=True)
        else:
            lines.append(json.dumps({"file": item, "model": getattr(model, "name", model_name),
                                     "latent": [round(v, 6) for v in z.tolist()]}))

    def work(group):
        good, bad = _load(group)
        yield from bad
        if good:
            for (item, _), z in zip(good, api.encode([img for _, img in good], model, fit=fit)):
                try:
                    write(item, z)
                    yield item, None
                except Im2VecError as exc:
                    yield item, exc

    try:
        run_batch(ctx, items, work, chunk=ENCODE_CHUNK)
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
    from .. import api
    from ..files import tensor_to_png

    refuse_overwrite([output], [svg_file])
    refuse_misnamed(output, "PNG")
    image = api.from_svg(api.read_svg_bytes(read_input(svg_file, limit=api.MAX_SVG_BYTES), svg_file))
    write_output(output, tensor_to_png(api.render_vector(image, scale=scale, tau=tau)))
