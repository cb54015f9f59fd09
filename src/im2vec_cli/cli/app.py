"""The ``im2vec`` click group: library errors become one ``Error:`` line and exit 1.

Exit codes: 0 success; 1 an error (bad input, bad model, failed write; some files of a
batch failed); 2 bad usage; 130 interrupted (Ctrl-C); 143 terminated (SIGTERM); 129 hung up (SIGHUP).
"""

from __future__ import annotations

import contextlib
import importlib
import signal
import traceback
import warnings

import click

from .. import __version__
from ..errors import Im2VecError, OptionWarning, describe

EXIT_HELP = ("Exit codes: 0 ok, 1 error (or some files of a batch failed), 2 bad usage, 130 interrupted, "
             "143 terminated, 129 hung up.")


class Terminated(BaseException):
    """SIGTERM or SIGHUP (``signum``), raised in the main thread as Ctrl-C raises
    ``KeyboardInterrupt``: the work in flight stops through every ``finally`` (worker processes
    ended, temp files removed)."""

    def __init__(self, signum: int = signal.SIGTERM):
        super().__init__(signum)
        self.signum = signum


def _terminated(signum, frame):
    raise Terminated(signum)


ENDING = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))  # as Ctrl-C


LAZY = {"train": "training", "train-aux": "training", "export": "training", "fit-prior": "training",
        "train-features": "training", "data": "datasets", "eval": "evaluation"}  # command -> its module, imported
# when the command runs or help lists it (the training commands' module alone cost `vectorize` 26 ms a call)


class Im2VecGroup(click.Group):
    """Turns library errors into one line on stderr and exit 1 (traceback with --debug);
    SIGTERM and Ctrl-C end a command cleanly (exit 143 and 130). The commands of ``LAZY``
    register when first asked for."""

    def get_command(self, ctx, cmd_name):
        if cmd_name not in self.commands and cmd_name in LAZY:
            importlib.import_module(f"{__package__}.{LAZY[cmd_name]}")
        return super().get_command(ctx, cmd_name)

    def list_commands(self, ctx):
        for module in sorted(set(LAZY.values())):
            importlib.import_module(f"{__package__}.{module}")
        return super().list_commands(ctx)

    def invoke(self, ctx):
        before = {signum: signal.signal(signum, _terminated) for signum in ENDING}
        try:
            return self._invoke(ctx)
        finally:
            for signum, handler in before.items():
                signal.signal(signum, handler)

    def _invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except Im2VecError as exc:
            fail(ctx, str(exc))
        except (click.exceptions.Exit, click.ClickException, click.Abort):
            raise
        except OSError as exc:  # unwritable output, full disk: still one line
            name = getattr(exc, "filename", None)
            fail(ctx, f"{name}: {exc.strerror or exc}" if name else f"{exc.strerror or exc}")
        except KeyboardInterrupt:
            click.echo("Interrupted.", err=True)
            ctx.exit(130)
        except Terminated as exc:
            click.echo("Terminated." if exc.signum == signal.SIGTERM else "Hung up.", err=True)
            ctx.exit(128 + exc.signum)  # 143 for SIGTERM, 129 for SIGHUP
        except Exception as exc:  # noqa: BLE001 - never a traceback: a dependency's error, memory running out
            fail(ctx, describe(exc))


def fail(ctx: click.Context, message: str):
    """Print ``Error: message`` (and the traceback with ``--debug``), exit 1."""
    if ctx.obj and ctx.obj.get("debug"):
        traceback.print_exc()
    click.echo(f"Error: {one_line(message)}", err=True)
    ctx.exit(1)


def one_line(message: str) -> str:
    """``message`` with its control characters escaped (``\\n`` for a newline in a file name), so
    that one error or warning stays one line."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in message)


@contextlib.contextmanager
def starting_up():
    """Imports and model loading without the cyclic garbage collector (``runtime.collector_paused``)."""
    from ..runtime import collector_paused

    with collector_paused():
        yield


def warn(message: str) -> None:
    """One ``Warning:`` line on stderr."""
    click.echo(f"Warning: {one_line(message)}", err=True)


@click.group(cls=Im2VecGroup, context_settings={"help_option_names": ["-h", "--help"]}, epilog=EXIT_HELP)
@click.version_option(__version__, prog_name="im2vec")
@click.option("--debug", is_flag=True, help="Show tracebacks on errors.")
@click.pass_context
def cli(ctx, debug):
    """im2vec: raster images to vector graphics (closed cubic Bezier paths) with a learned model."""
    warnings.filterwarnings("ignore", category=OptionWarning)  # the commands say these themselves, one line each
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug
