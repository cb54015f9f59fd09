"""``torch.compile`` with an eager fallback, shared by the renderer's hot functions.

``IM2VEC_COMPILE=0`` turns compilation off. Functions are compiled with ``dynamic=True``:
batch size, segment count and the culling capacity change from call to call, and one
symbolic compile per function serves them all instead of a recompile per shape.
"""

from __future__ import annotations

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


def compile_enabled() -> bool:
    """Whether hot functions go through ``torch.compile`` (``set_compile``, else env ``IM2VEC_COMPILE``, default on)."""
    if _broken:
        return False
    if _override is not None:
        return _override
    return os.environ.get("IM2VEC_COMPILE", "1").lower() not in ("0", "false", "no", "off")


def maybe_compile(fn: Callable) -> Callable:
    """Wrap ``fn`` so that it runs compiled when enabled, and eagerly otherwise or on failure."""
    compiled: list[Callable] = []

    @functools.wraps(fn)
    def wrapper(*args):
        global _broken
        if not compile_enabled():
            return fn(*args)
        if not compiled:
            compiled.append(torch.compile(fn, dynamic=True))
        try:
            return compiled[0](*args)
        except torch._dynamo.exc.BackendCompilerFailed:  # pragma: no cover - no working C compiler
            _broken = True
            return fn(*args)

    wrapper.eager = fn
    return wrapper
