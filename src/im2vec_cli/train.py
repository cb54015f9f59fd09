"""Training loop of ``im2vec train``: VAE on raster images only (paper sec. 3.4, 3.5).

Run directory layout::

    RUN/checkpoint.pt     model, optimiser, Lookahead, step and RNG states (atomic)
    RUN/metrics.jsonl     one JSON line per log / validation event
    RUN/preview_<step>.png  input | reconstruction | reconstruction with control points
    RUN/model/            exported model (config.json + model.safetensors)
    RUN/train_config.json
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from collections.abc import Callable
from pathlib import Path

import torch
import torch.distributed as dist
from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn

from .checkpoint import _unwrap, load_checkpoint, save_checkpoint, save_pretrained
from .config import ModelConfig, TrainConfig
from .data.folder import load_folder, split_indices
from .errors import DataError, Im2VecError, TrainingError
from .io import atomic_write
from .model.imagevae import build_model
from .model.vae import Im2Vec, kl_divergence
from .raster import gaussian_pyramid, pyramid_l2, render_pyramid
from .raster.render import PYRAMID_COARSE

MAX_NONFINITE_IN_A_ROW = 20  # skipped steps before training stops with an error


class Lookahead:
    """Lookahead (Zhang et al. 2019) around an inner optimiser; with RAdam this is Ranger."""

    def __init__(self, optimizer: torch.optim.Optimizer, k: int = 6, alpha: float = 0.5):
        self.optimizer, self.k, self.alpha, self.count = optimizer, k, alpha, 0
        self.slow = [p.detach().clone() for g in optimizer.param_groups for p in g["params"]]

    @property
    def param_groups(self):
        return self.optimizer.param_groups

    def zero_grad(self, set_to_none: bool = True):
        self.optimizer.zero_grad(set_to_none=set_to_none)

    @torch.no_grad()
    def step(self):
        self.optimizer.step()
        self.count += 1
        if self.count % self.k == 0:
            fast = [p for g in self.optimizer.param_groups for p in g["params"]]
            for s, f in zip(self.slow, fast):
                s.add_(f - s, alpha=self.alpha)
                f.copy_(s)

    def state_dict(self):
        return {"inner": self.optimizer.state_dict(), "slow": self.slow, "count": self.count}

    def load_state_dict(self, state):
        self.optimizer.load_state_dict(state["inner"])
        for s, v in zip(self.slow, state["slow"]):
            s.copy_(v)
        self.count = state["count"]


def schedule(step: int, tcfg: TrainConfig) -> dict[str, float]:
    """lr (cosine to ``lr * lr_final``), KL weight (linear warm-up) and tau (linear anneal)."""
    frac = min(1.0, step / max(1, tcfg.steps - 1))
    lr = tcfg.lr * (tcfg.lr_final + (1 - tcfg.lr_final) * 0.5 * (1 + math.cos(math.pi * frac)))
    beta = tcfg.beta * min(1.0, step / max(1, tcfg.beta_warmup))
    tau = tcfg.tau_start + (tcfg.tau_end - tcfg.tau_start) * frac
    return {"lr": lr, "beta": beta, "tau": tau}


def reconstruction_loss(model: Im2Vec, images: torch.Tensor, segments: int, tau: float, sample: bool,
                        supersample: int = 1, pyramid: str = "blur"):
    """Pyramid L2 (eq. 1) of the reconstruction, and the KL term. ``images (B, 3, S, S)``.
    ``supersample > 1`` renders the finest level from that many sub-pixels per side (``tau``
    in sub-pixels there), so the loss sees the edges a user's antialiased render shows.
    ``pyramid`` picks the coarser levels (``render_pyramid``'s ``coarse``).

    Returns ``(pyramid L2, KL, decoded)``: ``Decoded`` paths, or for the ImageVAE baseline its
    ``(B, 3, S, S)`` raster, scored by the same pyramid loss.
    """
    m = _unwrap(model)
    cfg = m.config
    dec, mu, logvar = model(images, segments, sample=sample)
    if m.raster_output:
        renders = gaussian_pyramid(dec, cfg.levels)
        return pyramid_l2(renders, gaussian_pyramid(images, cfg.levels)), kl_divergence(mu, logvar), dec
    renders = render_pyramid(
        dec.points, dec.colors, dec.depth, size=cfg.image_size, levels=cfg.levels, tau=tau,
        fill_rule=dec.fill_rule, shape_index=dec.shape_index, samples=cfg.samples, composite="soft",
        supersample=supersample, coarse=pyramid,
    )
    return pyramid_l2(renders, gaussian_pyramid(images, cfg.levels)), kl_divergence(mu, logvar), dec


@torch.no_grad()
def evaluate_l2(model: Im2Vec, images: torch.Tensor, segments: int, tau: float, batch: int = 128,
                supersample: int = 1, pyramid: str = "blur") -> dict[str, float]:
    """Validation: pyramid L2 and plain MSE (paper Table 1) with ``z = mu``.

    ``images`` uint8 ``(N, 3, S, S)``; the MSE render uses exact "over" compositing, and
    ``supersample`` and ``pyramid`` as the loss does.
    """
    m = _unwrap(model)
    was = m.training
    m.eval()
    dev = next(m.parameters()).device
    pyr, mse, n = 0.0, 0.0, 0
    for i in range(0, len(images), batch):
        x = images[i : i + batch].to(dev).float() / 255
        loss, _, dec = reconstruction_loss(m, x, segments, tau, sample=False, supersample=supersample,
                                           pyramid=pyramid)
        img = dec if m.raster_output else m.render(dec, tau=tau, composite="over", supersample=supersample)
        pyr += float(loss) * len(x)
        mse += float(((img - x) ** 2).mean()) * len(x)
        n += len(x)
    m.train(was)
    return {"val_pyramid_l2": pyr / n, "val_mse": mse / n}


def preview_grid(model: Im2Vec, images: torch.Tensor, segments: int, tau: float, scale: int = 2) -> bytes:
    """PNG rows of input | reconstruction | reconstruction with control points (anchors red;
    the ImageVAE baseline has none)."""
    from PIL import Image, ImageDraw

    m = _unwrap(model)
    with torch.no_grad():
        x = images.float() / 255
        dec, _, _ = m(x.to(next(m.parameters()).device), segments, sample=False)
        rec = (dec if m.raster_output else m.render(dec, tau=tau, composite="over")).cpu()
    s = m.config.image_size * scale
    sheet = Image.new("RGB", (3 * s, len(x) * s), "white")
    for r in range(len(x)):
        for c, img in enumerate((x[r], rec[r], rec[r])):
            tile = Image.fromarray((img.permute(1, 2, 0).clamp(0, 1) * 255).byte().numpy()).resize((s, s), Image.NEAREST)
            if c == 2 and not m.raster_output:
                draw = ImageDraw.Draw(tile)
                for path in dec.points[r].cpu():
                    for j, (px, py) in enumerate(path.tolist()):
                        col = (220, 30, 30) if j % 3 == 0 else (30, 90, 220)
                        draw.ellipse([px * s - 1.5, py * s - 1.5, px * s + 1.5, py * s + 1.5], fill=col)
            sheet.paste(tile, (c * s, r * s))
    import io as _io

    buf = _io.BytesIO()
    sheet.save(buf, format="PNG")
    return buf.getvalue()


def _dist_info() -> tuple[int, int]:
    if dist.is_available() and dist.is_initialized():
        return dist.get_rank(), dist.get_world_size()
    return 0, 1


def find_split_dirs(data_dir: Path) -> tuple[Path, Path | None]:
    """``DATA/train`` and ``DATA/val`` when the folder was built by ``im2vec data``."""
    if (data_dir / "train").is_dir() and (data_dir / "val").is_dir():
        return data_dir / "train", data_dir / "val"
    return data_dir, None


def train(
    data_dir: str | Path,
    run_dir: str | Path,
    model_cfg: ModelConfig,
    train_cfg: TrainConfig,
    *,
    device: torch.device = torch.device("cpu"),
    val_dir: str | Path | None = None,
    resume: bool = False,
    on_event: Callable[[dict], None] | None = None,
    images: torch.Tensor | None = None,
    epochs: float | None = None,
    init_state: dict[str, torch.Tensor] | None = None,
) -> Path:
    """Train an Im2Vec model (or the ImageVAE baseline, ``model_cfg.arch``); returns the
    exported model folder ``RUN/model``.

    Under ``torchrun`` (``WORLD_SIZE`` > 1) it runs DDP (gloo on CPU, nccl on CUDA); each
    rank draws its own batches and only rank 0 writes files. ``images`` (uint8
    ``(N, 3, S, S)``) bypasses the folder loading, for tests. ``epochs`` overrides
    ``train_cfg.steps`` by passes over the training images. ``init_state`` (a state dict of
    the same config) starts from trained weights with a fresh optimiser: fine-tuning.
    """
    emit = on_event or (lambda e: None)
    if train_cfg.supersample < 1:
        raise Im2VecError(f"supersample must be >= 1, got {train_cfg.supersample}")
    if train_cfg.pyramid not in PYRAMID_COARSE:
        raise Im2VecError(f"pyramid must be one of {PYRAMID_COARSE}, got {train_cfg.pyramid!r}")
    run_dir = Path(run_dir)
    if int(os.environ.get("WORLD_SIZE", "1")) > 1 and not dist.is_initialized():
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
        if device.type == "cuda":
            device = torch.device("cuda", int(os.environ.get("LOCAL_RANK", "0")))
            torch.cuda.set_device(device)
    rank, world = _dist_info()
    main = rank == 0
    if main:
        run_dir.mkdir(parents=True, exist_ok=True)

    # ---- model (first, so a bad config fails before the data loads)
    torch.manual_seed(train_cfg.seed)
    try:
        model = build_model(model_cfg).to(device)
    except ValueError as exc:
        raise Im2VecError(f"model config: {exc}") from None
    if init_state is not None:
        model.load_state_dict(init_state)  # copies into the parameters, casting fp16 storage

    # ---- data
    if images is None:
        data_dir = Path(data_dir)
        tr_dir, auto_val = find_split_dirs(data_dir)
        val_dir = Path(val_dir) if val_dir else auto_val
        skip = lambda msg: emit({"event": "skip", "message": msg}) if main else None  # noqa: E731
        images, names = load_folder(tr_dir, model_cfg.image_size, fit=model_cfg.fit, workers=train_cfg.workers, on_skip=skip)
        if val_dir is not None:
            train_x = images
            val_x, _ = load_folder(val_dir, model_cfg.image_size, fit=model_cfg.fit, workers=train_cfg.workers, on_skip=skip)
        else:
            tr, va = split_indices(names, train_cfg.val_fraction)
            train_x, val_x = images[tr], images[va]
    else:
        n_val = max(1, int(len(images) * train_cfg.val_fraction))
        train_x, val_x = images[:-n_val], images[-n_val:]
    if len(train_x) == 0:
        raise DataError("no training images left after the validation split")
    val_x = val_x[:: max(1, len(val_x) // 512)][:512]  # spread over the folder (sorted by class or family)
    if epochs:
        train_cfg = dataclasses.replace(train_cfg, steps=max(1, round(epochs * len(train_x) / train_cfg.batch)))
    emit({"event": "data", "train": len(train_x), "val": len(val_x), "steps": train_cfg.steps})

    # ---- optimiser
    opt = Lookahead(torch.optim.RAdam(model.parameters(), lr=train_cfg.lr), train_cfg.lookahead_k,
                    train_cfg.lookahead_alpha)
    if not 0.0 <= train_cfg.ema < 1.0:
        raise Im2VecError(f"ema must be in [0, 1), got {train_cfg.ema}")
    ema = None
    if train_cfg.ema > 0 and main:  # ema.module: the averaged copy (its first update copies the weights); only
        # rank 0 validates, previews and saves, and DDP keeps every rank's weights equal, so only it averages
        ema = AveragedModel(model, multi_avg_fn=get_ema_multi_avg_fn(train_cfg.ema), use_buffers=True)
    exported = ema.module if ema is not None else model  # the weights validation, previews and exports show
    gen = torch.Generator().manual_seed(train_cfg.seed * 1000 + rank)
    step = 0
    ckpt_path = run_dir / "checkpoint.pt"
    if resume:
        state = load_checkpoint(ckpt_path)
        if ModelConfig.from_dict(state["model_config"]) != model_cfg:
            raise Im2VecError(f"{ckpt_path}: was trained with a different model config")
        model.load_state_dict(state["model"])
        opt.load_state_dict(state["optimizer"])
        if ema is not None and state.get("ema") is not None:  # else its first update copies the weights
            ema.load_state_dict(state["ema"])
        step = state["step"]
        gen.set_state(state["generator"][rank] if rank < len(state["generator"]) else state["generator"][0])
        torch.set_rng_state(state["torch_rng"])
        if device.type == "cuda" and state.get("cuda_rng") is not None:
            torch.cuda.set_rng_state(state["cuda_rng"], device)
        emit({"event": "resume", "step": step})
    ddp_model = model
    if world > 1:
        # some heads are idle by configuration (colour with a palette, depth under even-odd)
        ddp_model = torch.nn.parallel.DistributedDataParallel(
            model, device_ids=[device.index] if device.type == "cuda" else None, find_unused_parameters=True
        )
    if main:
        atomic_write(run_dir / "train_config.json", train_cfg.to_json())
    metrics = run_dir / "metrics.jsonl"

    def log(rec: dict):
        emit(rec)
        if main:
            with open(metrics, "a") as f:
                f.write(json.dumps(rec) + "\n")

    def checkpoint():
        gens = [gen.get_state()]
        if world > 1:
            gathered = [torch.zeros_like(gens[0]) for _ in range(world)]
            dist.all_gather_object(gathered, gens[0])
            gens = gathered
        if main:
            save_checkpoint(ckpt_path, {
                "model": model.state_dict(), "optimizer": opt.state_dict(), "step": step, "generator": gens,
                "ema": ema.state_dict() if ema is not None else None,
                "torch_rng": torch.get_rng_state(),
                "cuda_rng": torch.cuda.get_rng_state(device) if device.type == "cuda" else None,
                "model_config": model_cfg.to_dict(), "train_config": train_cfg.to_dict(),
            })

    model.train()
    t_last, n_last = time.perf_counter(), 0
    bad_run = 0  # consecutive steps skipped for a non-finite loss or gradient
    try:
        while step < train_cfg.steps:
            sch = schedule(step, train_cfg)
            for g in opt.param_groups:
                g["lr"] = sch["lr"]
            idx = torch.randint(len(train_x), (train_cfg.batch,), generator=gen)
            k = int(torch.randint(model_cfg.min_segments, model_cfg.max_segments + 1, (1,), generator=gen))
            x = train_x[idx].to(device).float() / 255  # (B, 3, S, S)
            rec, kl, _ = reconstruction_loss(ddp_model, x, k, sch["tau"], sample=True,
                                             supersample=train_cfg.supersample, pyramid=train_cfg.pyramid)
            loss = rec + sch["beta"] * kl
            opt.zero_grad()
            loss.backward()
            gnorm = torch.nn.utils.clip_grad_norm_(model.parameters(), train_cfg.grad_clip)
            # gnorm is computed from the all-reduced gradients, so every DDP rank decides alike
            finite = bool(torch.isfinite(gnorm)) and (world > 1 or bool(torch.isfinite(loss)))
            step += 1
            if finite:
                opt.step()
                if ema is not None:
                    ema.update_parameters(model)
                bad_run = 0
            else:  # skip the update: the weights never see a NaN or inf
                opt.zero_grad()
                bad_run += 1
                log({"event": "nonfinite", "step": step, "loss": loss.item(), "grad_norm": gnorm.item(),
                     "in_a_row": bad_run, "time": time.time()})
                if bad_run >= MAX_NONFINITE_IN_A_ROW:
                    raise TrainingError(
                        f"the loss or gradient was not finite for {bad_run} steps in a row (up to step {step}); "
                        f"the last good checkpoint is {ckpt_path}; try a lower --lr"
                    )
            n_last += len(x) * world
            if step % train_cfg.log_every == 0 or step == train_cfg.steps:
                now = time.perf_counter()
                log({"event": "train", "step": step, "loss": loss.item(), "pyramid_l2": rec.item(), "kl": kl.item(),
                     "k": k, "lr": sch["lr"], "tau": sch["tau"], "grad_norm": float(gnorm),
                     "img_per_s": n_last / max(1e-9, now - t_last), "time": time.time()})
                t_last, n_last = now, 0
            if step % train_cfg.val_every == 0 or step == train_cfg.steps:
                if main:
                    val = lambda m: evaluate_l2(m, val_x, model_cfg.segments, train_cfg.tau_end,  # noqa: E731
                                                supersample=train_cfg.supersample, pyramid=train_cfg.pyramid)
                    rec = {"event": "val", "step": step, **val(model)}
                    if ema is not None:  # the averaged weights are the ones exported
                        rec = {**rec, **{f"raw_{k}": v for k, v in rec.items() if k not in ("event", "step")},
                               **val(exported)}
                    log({**rec, "time": time.time()})
            if main and (step % train_cfg.preview_every == 0 or step == train_cfg.steps):
                atomic_write(run_dir / f"preview_{step:07d}.png",
                             preview_grid(exported, val_x[:8], model_cfg.segments,
                                          train_cfg.tau_end))
            if step % train_cfg.ckpt_every == 0 or step == train_cfg.steps:
                checkpoint()
    except KeyboardInterrupt:
        checkpoint()
        raise
    if main:
        save_pretrained(exported, run_dir / "model")
    if world > 1:
        dist.barrier()
    return run_dir / "model"
