"""Batches of inputs: expanding folders, naming outputs, and running work over them while
reporting bad files as they come (psf/black's ``Report``: done/failed and the exit code)."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import click

from ..errors import DataError, Im2VecError
from .app import one_line, warn

Item = tuple[str, "Path | None"]  # (input path or "-", the folder it was found in, or None)


@dataclass
class Report:
    """Counts of a batch's inputs: done and failed. ``exit_code`` is 1 when any failed."""

    total: int
    done: int = 0
    failed: int = 0

    def success(self) -> None:
        self.done += 1

    def failure(self, message: str) -> None:
        self.failed += 1
        click.echo(f"Error: {one_line(message)}", err=True)

    @property
    def exit_code(self) -> int:
        return 1 if self.failed else 0

    def summary(self) -> str | None:
        """The closing line of a batch of several inputs with failures, else ``None``."""
        if self.failed and self.total > 1:
            return f"{self.failed} of {self.total} inputs failed"
        return None


def expand_inputs(inputs: Iterable[str]) -> list[Item]:
    """Files and folders (searched recursively for PNG/JPG) -> ``(path, folder or None)``.
    A file given twice is there twice (``dedupe_inputs`` keeps it once).

    What a folder holds under an image name that is not a regular file (a FIFO, a device, a
    broken link) is skipped with a warning; ``-`` (stdin) is an input only alone."""
    from ..api import list_images

    inputs = list(inputs)
    if "-" in inputs and len(inputs) > 1:
        raise click.UsageError("- (stdin) is one input on its own: give it alone, or give files")
    out: list[Item] = []
    for item in inputs:
        p = Path(item)
        if item != "-" and p.is_dir():
            try:
                found = list_images(p, on_skip=lambda msg: warn(f"skipped {msg}"))
            except DataError as exc:
                raise Im2VecError(str(exc)) from None
            if not found:
                raise Im2VecError(f"{p}: no images (.png, .jpg) in this folder")
            out += [(str(f), p) for f in found]
        else:
            out.append((item, None))
    return out


def dedupe_inputs(items: list[Item]) -> tuple[list[Item], list[str]]:
    """The inputs with every file given more than once (by path, through a link, or inside a
    folder also given) kept once, at its first place, and a note for each repeat."""
    seen: dict[object, str] = {}
    kept, notes = [], []
    for item, root in items:
        try:
            st = os.stat(item) if item != "-" else None
            key = (st.st_dev, st.st_ino) if st is not None else "-"
        except OSError:  # a missing input is reported when it is read
            key = os.path.realpath(item)
        if key in seen:
            notes.append(f"{item} is given twice (also as {seen[key]}): vectorized once" if item != seen[key]
                         else f"{item} is given twice: vectorized once")
            continue
        seen[key] = item
        kept.append((item, root))
    return kept, notes


def names_folder(output: str) -> bool:
    """Whether ``-o`` names a folder: an existing one, or any path that ends with a slash. A
    slash after the name of something that is not a folder is refused (``Im2VecError``): the
    user meant a folder, and the file there is not to be replaced."""
    if output == "-":
        return False
    slash = output.endswith(os.sep) or bool(os.altsep and output.endswith(os.altsep))
    path = Path(output)
    if slash and os.path.lexists(path) and not path.is_dir():
        raise Im2VecError(f"{output}: ends with a slash, which names a folder, but {path} is not a folder")
    return slash or path.is_dir()


RASTER_SUFFIXES = (".png", ".jpg", ".jpeg", ".gif", ".webp", ".bmp", ".tif", ".tiff")


def refuse_misnamed(output: str, writes: str) -> None:
    """A usage error when the file ``-o`` names says, by its suffix, another kind than the command
    ``writes`` (``"SVG"`` or ``"PNG"``): `vectorize -o out.png` wrote an SVG into a .png, silently."""
    suffix = Path(output).suffix.lower()
    wrong = suffix in RASTER_SUFFIXES if writes == "SVG" else suffix in (".svg", ".svgz")
    if output != "-" and wrong:
        raise click.UsageError(f"-o {output}: this writes {writes}; give the output a .{writes.lower()} name")


def check_writable_folder(output: str) -> None:
    """Make the output folder of several inputs and check that a file can be written there, once,
    before any work: a read-only folder, a path through a file or a file where the folder should
    be is one error line, not one per picture."""
    import errno
    import tempfile

    from .streams import make_folder

    out = Path(output)
    if os.path.lexists(out) and not out.is_dir():
        raise Im2VecError(f"{output}: not a folder (several inputs are written into a folder; give another -o)")
    make_folder(out)
    try:
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        why = exc.strerror or errno.errorcode.get(exc.errno, str(exc))
        raise Im2VecError(f"{output}: cannot write into this folder ({why})") from None


def _destination(item: str, root: Path | None, output: str, suffix: str, single: bool) -> str:
    """Where the result of one input goes: the file (or stdout) itself for a single input,
    else ``OUT/<name><suffix>`` (``OUT/<path under the folder>`` for inputs found in a folder)."""
    if single:
        if names_folder(output):
            return str(Path(output) / ((Path(item).stem if item != "-" else "stdin") + suffix))
        return output
    if root is not None:
        return str(Path(output) / Path(item).relative_to(root).with_suffix(suffix))
    return str(Path(output) / (Path(item).stem + suffix))


def plan_outputs(items: list[Item], output: str, suffix: str, single: bool) -> tuple[list[str], list[str]]:
    """The output of every input, decided before anything is written.

    Two inputs never share an output: where they would (``x.png`` and ``x.jpg`` -> ``x.svg``),
    each keeps its extension in the name (``x.png.svg``, ``x.jpg.svg``) and a note says so.
    An output that is one of the inputs (the same path, or the same file through a link) is
    refused (``refuse_overwrite``).

    Returns:
        The outputs, in the order of ``items``, and the notes to show.
    """
    dests = [_destination(item, root, output, suffix, single) for item, root in items]
    groups: dict[str, list[int]] = {}
    for i, d in enumerate(dests):
        groups.setdefault(d, []).append(i)
    notes = []
    for d, idx in groups.items():
        if len(idx) > 1 and d != "-":
            for i in idx:
                dests[i] = str(Path(d).with_name(Path(items[i][0]).name + suffix))
            notes.append(f"{', '.join(items[i][0] for i in idx)} would all be written to {d}; "
                         f"written as {', '.join(Path(dests[i]).name for i in idx)}")
    if len(set(dests) - {"-"}) < len([d for d in dests if d != "-"]):
        raise Im2VecError("two inputs would be written to the same output even with their extensions kept; "
                          "rename one of them")
    refuse_overwrite(dests, [item for item, _ in items])
    return dests, notes


def refuse_overwrite(outputs: Iterable[str | Path], inputs: Iterable[str | Path]) -> None:
    """A usage error if an output would replace an input (same path, or same file through a
    link). Inputs are indexed once (real paths and inode numbers), so a folder of N inputs
    costs O(N), not a comparison per pair."""
    by_path, by_inode = {}, {}
    for i in inputs:
        if str(i) in ("-", ""):
            continue
        by_path[os.path.realpath(i)] = str(i)
        try:
            st = os.stat(i)
            by_inode[(st.st_dev, st.st_ino)] = str(i)
        except OSError:  # a missing input is reported when it is read
            pass
    for out in outputs:
        if str(out) == "-":
            continue
        name = by_path.get(os.path.realpath(out))
        if name is None:
            try:
                st = os.stat(out)
                name = by_inode.get((st.st_dev, st.st_ino))
            except OSError:  # the output does not exist yet: it can only be an input by path
                pass
        if name is not None:
            raise click.UsageError(f"the output {out} is the input {name}: refusing to overwrite an input")


Work = Callable[[list[Item]], Iterator[tuple[str, "Im2VecError | None"]]]


def run_batch(ctx: click.Context, items: list[Item], work: Work, chunk: int = 1) -> Report:
    """Run ``work(group)`` over chunks of inputs, streaming: only one chunk is in memory.

    ``work`` yields ``(item, error_or_None)`` per input; bad inputs are reported as they
    come, the good ones finish, and the command exits 1 at the end if any failed.
    """
    from ..runtime import progress

    report = Report(len(items))
    bar = progress(total=len(items), desc="files", unit="file", disable=None if len(items) > 1 else True)
    for start in range(0, len(items), chunk):
        for _item, exc in work(items[start : start + chunk]):
            if exc is None:
                report.success()
            else:
                bar.clear()
                report.failure(str(exc))
            bar.update(1)
    bar.close()
    if report.summary():
        click.echo(f"Error: {report.summary()}", err=True)
    if report.exit_code:
        ctx.exit(report.exit_code)
    return report
