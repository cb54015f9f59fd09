"""Exported models: a folder with ``config.json`` (``ModelConfig``, sorted, with class name and
format version) beside ``model.safetensors`` (huggingface/diffusers' ``save_pretrained`` /
``from_pretrained``), looked up by name or directory.
(The lookup, ``config.resolve_model``, needs no torch.)
"""

from __future__ import annotations

import os
from pathlib import Path

import torch

from ..checkpoint import load_checkpoint
from ..config import DEFAULT_MODEL, ModelConfig, resolve_model
from ..errors import ModelError
from ..files import atomic_write, check_output_folder, replace_folder
from ..options import GROWABLE, fixed_on_init
from . import build_model
from .encoder import Feedback, PathPass
from .points import PointPass
from .prior import NEIGHBOURS_CONFIG, NEIGHBOURS_WEIGHTS, LatentPrior, NeighbourPrior

STORED_FLOATS = (torch.float32, torch.float16, torch.bfloat16)  # how a float weight may be stored (``half``: fp16)


def unwrap_model(model: torch.nn.Module) -> torch.nn.Module:
    """The plain module under DDP and ``torch.compile`` wrappers (keys without prefixes)."""
    while True:
        if hasattr(model, "_orig_mod"):
            model = model._orig_mod
        elif isinstance(model, torch.nn.parallel.DistributedDataParallel):
            model = model.module
        else:
            return model


def save_pretrained(model: torch.nn.Module, directory: str | Path, *, half: bool = False) -> Path:
    """Write ``config.json`` and ``model.safetensors`` (fp16 storage with ``half``), and the
    model's ``latent_prior`` and ``neighbour_prior`` (``model.prior``) when it has them."""
    from safetensors.torch import save

    model = unwrap_model(model)
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    state = {k: (v.half() if half and v.is_floating_point() else v).detach().cpu().contiguous()
             for k, v in model.state_dict().items()}
    atomic_write(directory / "model.safetensors", save(state, metadata={"format": "pt"}))
    atomic_write(directory / "config.json", model.config.to_json())
    save_priors(model, directory)
    return directory


def save_priors(model: torch.nn.Module, directory: str | Path) -> None:
    """Write the model's ``latent_prior`` and ``neighbour_prior`` (those it has) into ``directory``;
    a stored neighbour prior the model lacks is removed there (it was fitted to other latents)."""
    model, directory = unwrap_model(model), Path(directory)
    if getattr(model, "latent_prior", None) is not None:
        model.latent_prior.save(directory)
    if getattr(model, "neighbour_prior", None) is not None:
        model.neighbour_prior.save(directory)
        return
    for name in (NEIGHBOURS_WEIGHTS, NEIGHBOURS_CONFIG):
        path = directory / name
        if path.is_symlink() or path.is_file():  # the link or file only, never what a link points to
            path.unlink()


def from_pretrained(name_or_dir: str | os.PathLike = DEFAULT_MODEL, device: str | torch.device = "cpu"):
    """Rebuild the model (``Im2Vec``, or the ``ImageVAE`` baseline) from its folder and load
    the weights with strict keys."""
    from safetensors import SafetensorError
    from safetensors.torch import load_file

    folder = resolve_model(name_or_dir)
    cfg = ModelConfig.load(folder / "config.json")
    weights = folder / "model.safetensors"
    if not weights.is_file():
        raise ModelError(f"{folder}: model.safetensors is missing")
    try:
        state = load_file(str(weights))
    except (SafetensorError, OSError, ValueError) as exc:
        raise ModelError(f"{weights}: unreadable weights ({exc})") from None
    try:
        model = build_model(cfg)
    except ValueError as exc:
        raise ModelError(f"{folder}: bad config ({exc})") from None
    ref = model.state_dict()
    for k, v in state.items():  # before any cast: int8 weights would be cast silently
        if k in ref and v.dtype != ref[k].dtype and not (ref[k].is_floating_point() and v.dtype in STORED_FLOATS):
            raise ModelError(f"{weights}: {k} is stored as {str(v.dtype).removeprefix('torch.')}, "
                             f"the model holds {str(ref[k].dtype).removeprefix('torch.')}")
    state = {k: v.float() if v.is_floating_point() else v for k, v in state.items()}  # fp16 storage -> fp32
    for k, v in state.items():
        if k in ref and v.shape != ref[k].shape:
            raise ModelError(f"{weights}: {k} has shape {tuple(v.shape)}, config expects {tuple(ref[k].shape)}")
        if v.is_floating_point() and not torch.isfinite(v).all():
            raise ModelError(f"{weights}: {k} contains NaN or infinite values")
    try:
        model.load_state_dict(state, strict=True)
    except RuntimeError as exc:
        first = str(exc).splitlines()[1].strip() if len(str(exc).splitlines()) > 1 else str(exc)
        raise ModelError(f"{weights}: weights do not match the config ({first})") from None
    model.name, model.folder = folder.name, folder
    model.latent_prior = LatentPrior.load(folder)  # None when the folder stores none
    model.neighbour_prior = NeighbourPrior.load(folder)
    for prior in (model.latent_prior, model.neighbour_prior):
        if prior is not None and prior.latent != cfg.latent:
            raise ModelError(f"{folder}: latent prior is over {prior.latent} dimensions, "
                             f"the model's latent has {cfg.latent}")
    return model.to(device).eval()


def stored_half(name_or_dir: str | os.PathLike) -> bool:
    """Whether an exported model's floating-point weights are stored as fp16."""
    from safetensors import safe_open

    with safe_open(str(resolve_model(name_or_dir) / "model.safetensors"), framework="pt") as f:
        return any(f.get_slice(k).get_dtype() == "F16" for k in f.keys())


def export_checkpoint(run_dir: str | Path, out_dir: str | Path, *, half: bool = False,
                      overwrite: bool = False, raw: bool = False) -> tuple[Path, int]:
    """Export the model of a run's ``checkpoint.pt`` as a ``from_pretrained`` folder, with the
    run's latent priors when they were fitted to this checkpoint's weights (a run stopped early has
    none: ``im2vec fit-prior`` fits them). A run with a weight EMA exports the averaged weights, or
    with ``raw`` the trained ones (a short run whose average still lags: its ``raw_val_*`` figures).

    ``out_dir`` is made whole (``files.replace_folder``): a folder that holds files is replaced
    only with ``overwrite``, and never one that holds the run.

    Returns the folder and the step the checkpoint was taken at.
    """
    check_output_folder(out_dir, overwrite, run_dir, error=ModelError)
    state = load_checkpoint(Path(run_dir) / "checkpoint.pt")
    model = build_model(ModelConfig.from_dict(state["model_config"]))
    if state.get("ema") is not None and not raw:  # a run with TrainConfig.ema exports the averaged weights
        from torch.optim.swa_utils import AveragedModel

        averaged = AveragedModel(model, use_buffers=True)
        averaged.load_state_dict(state["ema"], strict=True)
        model = averaged.module
    else:
        model.load_state_dict(state["model"], strict=True)
    for name, prior in (("latent_prior", LatentPrior.load(run_dir)), ("neighbour_prior", NeighbourPrior.load(run_dir))):
        if prior is not None and prior.config.step == int(state["step"]):  # fitted by `train` to these weights
            setattr(model, name, prior)
    return replace_folder(out_dir, lambda tmp: save_pretrained(model, tmp, half=half)), int(state["step"])


def grow_state(state: dict[str, torch.Tensor], old: ModelConfig, new: ModelConfig,
               seed: int = 0) -> dict[str, torch.Tensor]:
    """A state dict of ``old`` made to load into a model of ``new``, which may differ from it in
    ``GROWABLE`` keys only (fine-tuning into more paths, another grouping, or learned colours).

    The LSTM runs over any number of steps, so only the per-path step embeddings
    ``codes.step (P, D)`` depend on the path count: path ``i`` of the new model starts from
    old path ``i mod P_old`` plus noise of the embeddings' initial scale (0.02), so duplicated
    paths can part. A fixed palette may be dropped (``palette=""``: colours learned): its
    ``palette_logits`` go, and the colour head ``codes.color``, which a palette model carries
    untrained, learns. A feedback pass (``feedback``) added starts from fresh weights whose
    step is zero (``Feedback``), so the grown model encodes what ``old`` did; one removed is
    dropped; so is a path pass (``path_passes``, ``PathPass``: its last layer starts at zero), and a
    point pass (``point_passes``, ``PointPass``, likewise).
    The per-path inputs of ``feedback_paths`` added to a feedback pass (or new paths'
    ones) start with zero weights in its first layer, so they too change nothing at first.
    Every other tensor has the same shape in both configs and is copied.
    """
    import dataclasses

    changed = sorted(k for k in dataclasses.asdict(old) if getattr(old, k) != getattr(new, k))
    bad = fixed_on_init(dataclasses.asdict(new), dataclasses.asdict(old))
    if bad:
        raise ModelError(f"only {', '.join(GROWABLE)} can change when fine-tuning; the model's {', '.join(bad)} differ")
    if "palette" in changed and new.palette:
        raise ModelError("a fine-tune can drop a model's palette (learn colours), not give it another one")
    if old.path_passes and new.path_passes and old.path_pass_width != new.path_pass_width:
        raise ModelError("path_pass_width can change only where the path pass is added (the model has none)")
    if old.point_passes and new.point_passes and old.point_pass_width != new.point_pass_width:
        raise ModelError("point_pass_width can change only where the point pass is added (the model has none)")
    out = {k: v for k, v in state.items() if (new.palette or not k.startswith("palette_logits."))
           and (new.feedback or not k.startswith("feedback.")) and (new.path_passes or not k.startswith("path_pass."))
           and (new.point_passes or not k.startswith("point_pass."))}
    if new.path_passes and not old.path_passes:
        out.update(_fresh("path_pass", seed, lambda: PathPass(new.image_size, new.channels, new.code,
                                                               new.path_pass_width)))
    if new.point_passes and not old.point_passes:
        out.update(_fresh("point_pass", seed, lambda: PointPass(new.channels, new.point_pass_width,
                                                                         smooth=new.point_smooth)))
    if new.feedback and not old.feedback:
        out.update(_fresh("feedback", seed, lambda: Feedback(new.image_size, new.channels, new.latent, new.enc_width,
                                                              new.paths if new.feedback_paths else 0)))
    elif new.feedback:  # the feedback's inputs: 3C channels, then one per path with feedback_paths
        first = out["feedback.net.0.weight"]  # (O, 3C [+ P_old], 4, 4)
        keep = 3 * new.channels + (min(old.paths, new.paths) if old.feedback_paths and new.feedback_paths else 0)
        add = 3 * new.channels + (new.paths if new.feedback_paths else 0) - keep
        out["feedback.net.0.weight"] = torch.cat([first[:, :keep], first.new_zeros(first.shape[0], add, 4, 4)], 1)
    step = state.get("codes.step")
    if step is not None and step.shape[0] != new.paths:
        gen = torch.Generator().manual_seed(seed)
        rows = step.float()[torch.arange(new.paths) % step.shape[0]]  # (P_new, D)
        fresh = torch.arange(new.paths) >= step.shape[0]
        noise = torch.randn(rows.shape, generator=gen) * 0.02
        out["codes.step"] = (rows + noise * fresh[:, None]).to(step.dtype)
    return out


def _fresh(prefix: str, seed: int, build) -> dict[str, torch.Tensor]:
    """The state of a module ``build()`` makes under ``seed`` (the global generator left as it
    was), its keys under ``prefix``: a module a fine-tune adds (``grow_state``)."""
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        module = build()
    return {f"{prefix}.{k}": v for k, v in module.state_dict().items()}
