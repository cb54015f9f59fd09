"""Training checkpoints: ``checkpoint.pt`` in the run directory (model, optimiser, step and
RNG states), written atomically (``torch.save`` to memory, then a rename).

Exported model folders (``save_pretrained`` / ``from_pretrained``) live in ``model/pretrained.py``.
"""

from __future__ import annotations

import io
import pickle
import warnings
from pathlib import Path

import torch

from .errors import ModelError
from .files import atomic_write


def save_checkpoint(path: str | Path, state: dict) -> None:
    """Atomically write a training checkpoint (``torch.save`` to memory, then rename)."""
    buf = io.BytesIO()
    torch.save(state, buf)
    atomic_write(path, buf.getvalue())


REQUIRED = {"model": dict, "model_config": dict, "step": int}  # what every reader of a checkpoint uses


def load_checkpoint(path: str | Path) -> dict:
    """Read a training checkpoint; a missing, unreadable or malformed one is a one-line
    ``ModelError``. Tensors and plain containers only (``weights_only=True``): a crafted file
    cannot run code when it is read."""
    try:
        with warnings.catch_warnings():  # torch warns about pickle protocols on stderr: one line is ours
            warnings.simplefilter("ignore")
            state = torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise ModelError(f"{path}: no checkpoint to resume from") from None
    except pickle.UnpicklingError:
        raise ModelError(f"{path}: refused: holds more than tensors and plain data (not read)") from None
    except Exception as exc:
        raise ModelError(f"{path}: unreadable checkpoint ({type(exc).__name__})") from None
    if not isinstance(state, dict):
        raise ModelError(f"{path}: not a checkpoint (a {type(state).__name__}, not a dict)")
    for key, kind in REQUIRED.items():
        if not isinstance(state.get(key), kind):
            raise ModelError(f"{path}: not a checkpoint ({key!r} missing or not a {kind.__name__})")
    return state
