"""Options shared by several commands, and their parsers (``--segments``, ``--sweep``)."""

from __future__ import annotations

import click


def device_option(f):
    return click.option("--device", default="auto", show_default=True, help="auto, cpu, cuda[:N] or mps.")(f)


def model_options(f):
    """``--model``, ``--device`` and ``--seed``."""
    f = click.option("--seed", type=SEED, default=0, show_default=True, help="Random seed.")(f)
    f = device_option(f)
    f = click.option("--model", "model_name", default="fonts", show_default=True,
                     help="Shipped model name (see models/) or a directory written by `train`.")(f)
    return f


def set_threads_for(pictures: int) -> int:
    """Torch's threads for a command's work on ``pictures`` pictures (``runtime.intra_op_threads``:
    one for one picture, else the cores other programs leave free, read before torch runs
    anything), so that no command spins threads on a core another program holds (`interpolate`
    took 27-43 s instead of 3 s on a busy 2-core machine). Returns the free cores counted."""
    from .app import starting_up

    with starting_up():
        from .. import runtime
    free = runtime.free_cores() if pictures > 1 else 1
    runtime.set_threads(runtime.intra_op_threads(pictures, free=free))
    return free


def lazy_model(name: str, device: str, seed: int):
    """``load_model``'s model as an ``api.ModelRef``, loaded where a picture first needs it (one
    traced and not polished does not: neither the model nor torch is loaded for it), with the
    collector paused (``starting_up``). Checked now: the name, the folder (``check_model_folder``),
    that the model draws paths, and the device's name; Python, NumPy and (when it loads) torch seeded."""
    from ..api import ModelRef
    from ..config import check_model_folder, resolve_model
    from ..runtime import check_device, seed_everything
    from .app import starting_up

    seed_everything(seed)
    if check_model_folder(resolve_model(name)).arch == "imagevae":
        raise _draws_pixels(name)
    check_device(device)

    def load():
        with starting_up():  # torch's import and the model without the collector: 0.2-0.3 s less
            from .. import api

            return api.load_model(name, device)  # (torch_ready gives torch the seed)

    return ModelRef(load=load)


def load_model(name: str, device: str, seed: int, raster_ok: bool = False):
    """The model for a command, seeded; the ImageVAE baseline only where ``raster_ok``."""
    from .app import starting_up

    with starting_up():
        from ..api import load_model as load
        from ..runtime import seed_everything

        seed_everything(seed)
        model = load(name, device)
    if model.raster_output and not raster_ok:
        raise _draws_pixels(name)
    return model


def _draws_pixels(name: str):
    from ..errors import ModelError

    return ModelError(f"{name} is an ImageVAE baseline: it draws pixels, not paths (only `im2vec eval` takes it)")


def parse_segments(value: str | None) -> int | str | None:
    """``--segments``: a whole number in [1, 200], ``auto``, or unset."""
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


def parse_sweep(text: str) -> list[int]:
    """``--sweep``: ``"6-25"`` -> ``[6, ..., 25]``."""
    lo, sep, hi = text.partition("-")
    if not (sep and lo.strip().isdigit() and hi.strip().isdigit()) or not 1 <= int(lo) <= int(hi) <= 256:
        raise click.BadParameter(f"expected K1-K2 with 1 <= K1 <= K2 <= 256, got {text!r}", param_hint="--sweep")
    return list(range(int(lo), int(hi) + 1))


def nonempty(ctx, param, value):
    """Click callback: refuse ``""`` for a path argument, naming it (``""`` is not the current folder)."""
    if value is None:  # an unset option
        return value
    values = value if isinstance(value, tuple) else (value,)
    if any(v == "" for v in values):
        raise click.BadParameter("is empty (give a path)", ctx=ctx, param=param)
    return value


class Finite(click.FloatRange):
    """``click.FloatRange`` that also refuses NaN and infinities (which pass any range check)."""

    name = "finite float"

    def convert(self, value, param, ctx):
        import math

        rv = super().convert(value, param, ctx)
        if not math.isfinite(rv):
            self.fail(f"{value!r} is not a finite number", param, ctx)
        return rv


SEED = click.IntRange(0, 2**32 - 1)  # every RNG takes it (NumPy's is 32-bit); larger seeds are usage errors


class Bytes(click.ParamType):
    """A size in bytes: ``800M``, ``1.5G``, ``2048K`` or a plain number of bytes, at least
    ``options.MEMORY_MIN``."""

    name = "size"
    UNITS = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}

    def convert(self, value, param, ctx):
        import math

        from ..options import MEMORY_MIN

        if isinstance(value, int):
            return value
        text = str(value).strip().upper().removesuffix("B").removesuffix("I")
        unit = text[-1:] if text[-1:] in "KMGT" else ""
        try:
            number = float(text[: len(text) - len(unit)])
        except ValueError:
            self.fail(f"{value!r} is not a size (e.g. 800M, 2G)", param, ctx)
        if not math.isfinite(number * self.UNITS[unit]):
            self.fail(f"{value!r} is not a finite size (e.g. 800M, 2G)", param, ctx)
        if number * self.UNITS[unit] < MEMORY_MIN:
            self.fail(f"{value!r}: at least {MEMORY_MIN // 2**20}M", param, ctx)
        return int(number * self.UNITS[unit])


BYTES = Bytes()
