"""``torch.compile`` with an eager fallback, shared by the renderer's hot functions.

``IM2VEC_COMPILE=0`` turns compilation off. Batch size, segment count and the culling
capacities change from call to call, so those sizes are compiled as symbolic and one graph
serves them all instead of a recompile per shape; raster sizes and int arguments of the
pixel kernels are specialised (see ``maybe_compile``).
"""

from __future__ import annotations

import contextlib
import functools
import os
from collections.abc import Callable

import torch
import torch.fx.experimental._config as _fx_config

# Duck sizing ties symbols whose sizes happen to coincide (batch 64 and 64 pixels), which
# forces a recompile when they later differ; we never rely on such equalities.
_fx_config.use_duck_shape = False
_broken = False
_override: bool | None = None


def set_compile(enabled: bool | None) -> None:
    """Force compilation on or off for this process (``None``: back to ``IM2VEC_COMPILE``).

    One-image commands turn it off: a compile costs tens of seconds on CPU, far more than it saves.
    """
    global _override
    _override = enabled


@contextlib.contextmanager
def compiling(enabled: bool):
    """Within the block, compile (or not) as ``enabled`` says, unless ``IM2VEC_COMPILE`` is set,
    which always wins; the previous setting is restored after."""
    global _override
    saved = _override
    if "IM2VEC_COMPILE" not in os.environ:
        _override = enabled
    try:
        yield
    finally:
        _override = saved


def compile_enabled() -> bool:
    """Whether hot functions go through ``torch.compile`` (``set_compile``, else env ``IM2VEC_COMPILE``, default on)."""
    if _broken:
        return False
    if _override is not None:
        return _override
    return os.environ.get("IM2VEC_COMPILE", "1").lower() not in ("0", "false", "no", "off")


def maybe_compile(fn: Callable | None = None, *, dynamic: dict[int, tuple[int, ...]] | None = None):
    """Wrap ``fn`` so that it runs compiled when enabled, and eagerly otherwise or on failure.

    Args:
        dynamic: ``{argument position: dims}``, the only tensor dims compiled as symbolic
            sizes; every other size and every int argument is specialised (one graph per
            value, e.g. per pyramid level). Symbolic raster sizes in index arithmetic make
            inductor's CPU loops 3-5x slower, so kernels that index by pixel say which dims
            truly vary (batch, edge and candidate counts). ``None``: everything symbolic.

    Use as ``@maybe_compile`` or ``@maybe_compile(dynamic={0: (0,)})``.
    """
    if fn is None:
        return functools.partial(maybe_compile, dynamic=dynamic)
    compiled: list[Callable] = []

    @functools.wraps(fn)
    def wrapper(*args):
        global _broken
        if not compile_enabled():
            return fn(*args)
        if not compiled:
            compiled.append(torch.compile(fn, dynamic=dynamic is None))
        for pos, dims in (dynamic or {}).items():
            for d in dims:
                torch._dynamo.maybe_mark_dynamic(args[pos], d)
        try:
            return compiled[0](*args)
        except torch._dynamo.exc.BackendCompilerFailed:  # pragma: no cover - no working C compiler
            _broken = True
            return fn(*args)

    wrapper.eager = fn
    return wrapper
