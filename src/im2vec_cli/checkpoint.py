"""Training checkpoints: ``checkpoint.pt`` in the run directory (model, optimiser, step and
RNG states), written atomically (``torch.save`` to memory, then a rename).

Exported model folders (``save_pretrained`` / ``from_pretrained``) live in ``model/pretrained.py``.
"""

from __future__ import annotations

import io
import os
import pickle
import warnings
from pathlib import Path

import torch

from .errors import Im2VecError, ModelError
from .files import atomic_write


def save_checkpoint(path: str | Path, state: dict) -> None:
    """Atomically write a training checkpoint (``torch.save`` to memory, then rename)."""
    buf = io.BytesIO()
    torch.save(state, buf)
    atomic_write(path, buf.getvalue())


REQUIRED = {"model": dict, "model_config": dict, "step": int}  # what every reader of a checkpoint uses


def resumed_configs(run_dir: str | Path, model_given: dict, train_given: dict) -> tuple[dict, dict]:
    """The model and train configs a resumed run goes on with: its checkpoint's, with the
    ``given`` keys over them (so ``--resume`` alone continues exactly, and a phase config that
    names only what it changes resumes; a model key that differs from the checkpoint's is
    refused when the weights load)."""
    state = load_checkpoint(Path(run_dir) / "checkpoint.pt")
    return {**(state.get("model_config") or {}), **model_given}, {**(state.get("train_config") or {}), **train_given}


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


TEACHER_FILE = "teacher.safetensors"  # a distillation run's fitted latents (distill.Teacher)
RUN_FILES = ("checkpoint.pt", "metrics.jsonl", "train_config.json", "latent_prior.json", "latent_prior.safetensors",
             "latent_neighbours.json", "latent_neighbours.safetensors", "model", "preview_*.png", TEACHER_FILE)  # what a run writes: a new run in its folder starts without them


def prepare_run_dir(run_dir: Path, resume: bool, overwrite: bool, data_dir: str | Path | None = None) -> None:
    """Check ``run_dir`` before any work: ``resume`` needs a checkpoint; a run there is kept
    unless ``overwrite`` (then its files go, so that old and new never mix)."""
    import shutil

    if resume and overwrite:
        raise Im2VecError("resume continues a run and overwrite starts it over: give one of them")
    if os.path.lexists(run_dir) and not run_dir.is_dir():
        raise Im2VecError(f"{run_dir}: not a folder")
    if data_dir is not None and Path(data_dir).resolve() in [run_dir.resolve(), *run_dir.resolve().parents]:
        raise Im2VecError(f"{run_dir}: inside the training images' folder {data_dir} (its previews would become "
                          "training images); give the run a folder outside it")
    found = sorted(p for pattern in RUN_FILES for p in run_dir.glob(pattern)) if run_dir.is_dir() else []
    if resume:
        if not (run_dir / "checkpoint.pt").is_file():
            raise Im2VecError(f"{run_dir}: no checkpoint.pt to resume from")
    elif found and not overwrite:
        raise Im2VecError(f"{run_dir}: holds a training run ({found[0].name}, ...); --resume continues it, "
                          "--overwrite starts it over, --out names another folder")
    elif found:
        for p in found:
            shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()
    run_dir.mkdir(parents=True, exist_ok=True)
