"""Training checkpoints: ``checkpoint.pt`` in the run directory (model, optimiser, step and
RNG states), written atomically (``torch.save`` to memory, then a rename).

Exported model folders (``save_pretrained`` / ``from_pretrained``) live in ``model/pretrained.py``.
"""

from __future__ import annotations

import io
from pathlib import Path

import torch

from .errors import ModelError
from .files import atomic_write


def save_checkpoint(path: str | Path, state: dict) -> None:
    """Atomically write a training checkpoint (``torch.save`` to memory, then rename)."""
    buf = io.BytesIO()
    torch.save(state, buf)
    atomic_write(path, buf.getvalue())


def load_checkpoint(path: str | Path) -> dict:
    """Read a training checkpoint; a missing or unreadable one is a one-line ``ModelError``."""
    try:
        return torch.load(path, map_location="cpu", weights_only=False)
    except FileNotFoundError:
        raise ModelError(f"{path}: no checkpoint to resume from") from None
    except Exception as exc:
        raise ModelError(f"{path}: unreadable checkpoint ({type(exc).__name__})") from None
