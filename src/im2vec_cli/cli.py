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


def _read_input(path: str) -> bytes:
    if path == "-":
        return sys.stdin.buffer.read()
    from pathlib import Path

    try:
        return Path(path).read_bytes()
    except FileNotFoundError:
        raise Im2VecError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise Im2VecError(f"{path}: is a directory") from None


def _write_output(path: str, data: bytes) -> None:
    if path == "-":
        sys.stdout.buffer.write(data)
        sys.stdout.buffer.flush()
        return
    from .io import atomic_write

    atomic_write(path, data)


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


def main():
    cli(prog_name="im2vec")
