"""Device resolution, seeding and progress bars."""

from __future__ import annotations

import random
import sys

import numpy as np
import torch

from .errors import Im2VecError


def resolve_device(spec: str = "auto") -> torch.device:
    """``auto`` -> CUDA if present, then MPS, else CPU; otherwise validate ``cpu|cuda[:N]|mps``."""
    if spec == "auto":
        if torch.cuda.is_available():
            return torch.device("cuda")
        if getattr(torch.backends, "mps", None) is not None and torch.backends.mps.is_available():
            return torch.device("mps")
        return torch.device("cpu")
    try:
        dev = torch.device(spec)
    except (RuntimeError, ValueError):
        raise Im2VecError(f"unknown device {spec!r} (use auto, cpu, cuda[:N] or mps)") from None
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise Im2VecError(f"device {spec!r} asked for but CUDA is not available")
    if dev.type == "cuda" and dev.index is not None and dev.index >= torch.cuda.device_count():
        raise Im2VecError(f"device {spec!r} does not exist ({torch.cuda.device_count()} CUDA devices)")
    if dev.type == "mps" and not (getattr(torch.backends, "mps", None) and torch.backends.mps.is_available()):
        raise Im2VecError("device 'mps' asked for but MPS is not available")
    if dev.type not in ("cpu", "cuda", "mps"):
        raise Im2VecError(f"unsupported device {spec!r}")
    return dev


def seed_everything(seed: int) -> None:
    """Seed Python, NumPy and torch (all devices)."""
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)


def progress(iterable=None, **kwargs):
    """A tqdm bar on stderr that hides itself when stderr is not a terminal."""
    from tqdm.auto import tqdm

    kwargs.setdefault("disable", not sys.stderr.isatty())
    kwargs.setdefault("file", sys.stderr)
    kwargs.setdefault("dynamic_ncols", True)
    return tqdm(iterable, **kwargs)
