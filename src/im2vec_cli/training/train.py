"""Training loop of ``im2vec train``: VAE on raster images only (paper sec. 3.4, 3.5).

Run directory layout::

    RUN/checkpoint.pt     model, optimiser, Lookahead, EMA, step and RNG states (atomic)
    RUN/metrics.jsonl     one JSON line per log / validation event
    RUN/preview_<step>.png  input | reconstruction | reconstruction with control points
    RUN/model/            exported model (config.json + model.safetensors)
    RUN/train_config.json
    RUN/latent_prior.*    the latent prior fitted when the run finished (for ``export``)
    RUN/teacher.safetensors  the fitted latents a distillation phase learns (``distill``)

``train`` reads top to bottom: distributed set-up, the model, the splits, the ``TrainState`` (fresh
or resumed), then the loop of ``train_step`` and the periodic jobs (log, validate, preview, save).
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import torch
import torch.distributed as dist
from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn

from ..checkpoint import load_checkpoint, prepare_run_dir, save_checkpoint
from ..config import ModelConfig, TrainConfig
from ..data.augment import augment_batch
from ..data.folder import find_split_dirs, load_folder, split_indices
from ..errors import DataError, Im2VecError, TrainingError
from ..events import (
    DataLoaded,
    Event,
    NonFinite,
    NoPrior,
    PriorFitting,
    Resumed,
    Skipped,
    Teaching,
    TimeUp,
    Tracing,
    TrainStep,
    Validated,
)
from ..files import atomic_write
from ..model import build_model, flatten_rnns
from ..model.losses import reconstruction_loss
from ..model.pretrained import save_pretrained, save_priors
from ..model.prior import IMAGES_PER_COMPONENT, fit_neighbours, fit_prior, most_neighbours, posterior_means
from ..optim import Lookahead
from ..runtime import HeldSignals, setup_distributed
from .distill import Teacher, distill_loss, freeze, load_or_fit_teacher
from .outline import Outlines, trace_targets
from .validate import evaluate_l2, preview_grid

MAX_NONFINITE_IN_A_ROW = 20  # skipped steps before training stops with an error
MIN_IMAGES = 2  # one to train on, one to validate
PRIOR_MIN_IMAGES = 2  # training images a latent prior is fitted to (GaussianMixture needs two)
VAL_IMAGES = 512  # validation images, spread over the folder (sorted by class or family)

__all__ = ["TrainState", "evaluate_l2", "preview_grid", "schedule", "train", "TrainingError"]


def schedule(step: int, tcfg: TrainConfig) -> dict[str, float]:
    """lr (cosine to ``lr * lr_final``), KL weight (linear warm-up) and tau (linear anneal)."""
    frac = min(1.0, step / max(1, tcfg.steps - 1))
    lr = tcfg.lr * (tcfg.lr_final + (1 - tcfg.lr_final) * 0.5 * (1 + math.cos(math.pi * frac)))
    beta = tcfg.beta * min(1.0, step / max(1, tcfg.beta_warmup))
    tau = tcfg.tau_start + (tcfg.tau_end - tcfg.tau_start) * frac
    return {"lr": lr, "beta": beta, "tau": tau}


def load_splits(data_dir: str | Path | None, val_dir: str | Path | None, model_cfg: ModelConfig,
                train_cfg: TrainConfig, images: torch.Tensor | None, on_skip: Callable[[str], None]
                ) -> tuple[torch.Tensor, torch.Tensor]:
    """Training and validation images, uint8 ``(N, 3, S, S)``: ``data_dir``'s own split, a
    ``val_dir``, or a deterministic split by folder (``split_indices``); ``images`` bypasses
    the folders (tests: its last ``val_fraction`` is the validation set)."""
    if images is not None:
        n_val = max(1, int(len(images) * train_cfg.val_fraction))
        train_x, val_x = images[:-n_val], images[-n_val:]
    else:
        tr_dir, auto_val = find_split_dirs(Path(data_dir))
        val_dir = Path(val_dir) if val_dir else auto_val
        load = lambda d: load_folder(d, model_cfg.image_size, fit=model_cfg.fit,  # noqa: E731
                                     workers=train_cfg.workers, on_skip=on_skip)
        images, names = load(tr_dir)
        if val_dir is None and len(images) < MIN_IMAGES:
            raise DataError(f"{data_dir}: {len(images)} readable image{'s' * (len(images) != 1)}; training needs "
                            f"at least {MIN_IMAGES} (one to train on, one to validate), or a --val folder")
        if val_dir is not None:
            train_x, val_x = images, load(val_dir)[0]
        else:
            tr, va = split_indices(names, train_cfg.val_fraction)
            train_x, val_x = images[tr], images[va]
    if len(train_x) == 0:
        raise DataError("no training images left after the validation split")
    if len(val_x) == 0:
        raise DataError(f"{val_dir}: no readable validation images")
    return train_x, val_x[:: max(1, len(val_x) // VAL_IMAGES)][:VAL_IMAGES]


@dataclass
class TrainState:
    """Everything a run resumes from: the model, the optimiser, the EMA copy (rank 0), the
    batch generator, the step, a distillation phase's ``Teacher`` (kept in its own file) and an
    outline phase's traced ``Outlines`` (traced anew). ``save`` writes it atomically; ``load``
    restores it exactly."""

    model: torch.nn.Module
    opt: Lookahead
    ema: AveragedModel | None
    gen: torch.Generator
    step: int = 0
    teacher: Teacher | None = None
    outlines: Outlines | None = None

    @classmethod
    def create(cls, model: torch.nn.Module, cfg: TrainConfig, rank: int) -> TrainState:
        opt = Lookahead(torch.optim.RAdam(model.parameters(), lr=cfg.lr), cfg.lookahead_k, cfg.lookahead_alpha)
        ema = None
        if cfg.ema > 0 and rank == 0:  # only rank 0 validates, previews and saves (DDP keeps the ranks equal)
            ema = AveragedModel(model, multi_avg_fn=get_ema_multi_avg_fn(cfg.ema), use_buffers=True)
            flatten_rnns(ema.module)  # the averaged copy, a deepcopy: its first update copies the weights in place
        return cls(model, opt, ema, torch.Generator().manual_seed(cfg.seed * 1000 + rank))

    @property
    def exported(self) -> torch.nn.Module:
        """The weights validation, previews and exports show: the EMA copy when there is one."""
        return self.ema.module if self.ema is not None else self.model

    def save(self, path: Path, model_cfg: ModelConfig, train_cfg: TrainConfig, rank: int, world: int) -> None:
        """Checkpoint (every rank takes part: the generators are gathered; rank 0 writes)."""
        gens = [self.gen.get_state()]
        if world > 1:
            gathered = [torch.zeros_like(gens[0]) for _ in range(world)]
            dist.all_gather_object(gathered, gens[0])
            gens = gathered
        if rank != 0:
            return
        device = next(self.model.parameters()).device
        save_checkpoint(path, {
            "model": self.model.state_dict(), "optimizer": self.opt.state_dict(), "step": self.step, "generator": gens,
            "ema": self.ema.state_dict() if self.ema is not None else None, "torch_rng": torch.get_rng_state(),
            "cuda_rng": torch.cuda.get_rng_state(device) if device.type == "cuda" else None,
            "model_config": model_cfg.to_dict(), "train_config": train_cfg.to_dict(),
        })

    def load(self, path: Path, model_cfg: ModelConfig, rank: int) -> None:
        """Resume from ``path`` exactly: weights, optimiser, EMA, step and every RNG."""
        state = load_checkpoint(path)
        if ModelConfig.from_dict(state["model_config"]) != model_cfg:
            raise Im2VecError(f"{path}: was trained with a different model config")
        self.model.load_state_dict(state["model"])
        self.opt.load_state_dict(state["optimizer"])
        if self.ema is not None and state.get("ema") is not None:  # else its first update copies the weights
            self.ema.load_state_dict(state["ema"])
        self.step = state["step"]
        self.gen.set_state(state["generator"][rank] if rank < len(state["generator"]) else state["generator"][0])
        torch.set_rng_state(state["torch_rng"])
        device = next(self.model.parameters()).device
        if device.type == "cuda" and state.get("cuda_rng") is not None:
            torch.cuda.set_rng_state(state["cuda_rng"], device)


def train_step(state: TrainState, ddp_model: torch.nn.Module, train_x: torch.Tensor, model_cfg: ModelConfig,
               cfg: TrainConfig, world: int) -> dict:
    """One optimiser step on a random batch at a random k (sec. 3.5). A non-finite loss or
    gradient skips the update, so the weights never see a NaN or inf.

    With a ``teacher`` the batch is drawn from its images and ``cfg.distill`` times ``distill_loss``
    joins the loss; with ``outlines``, ``cfg.outline`` times ``outline_loss``; ``cfg.augment`` mirrors
    and shifts the batch. Returns loss, pyramid L2, KL, (distill, outline,) k, lr, tau, gradient norm, finite."""
    sch = schedule(state.step, cfg)
    for g in state.opt.param_groups:
        g["lr"] = sch["lr"]
    device = next(state.model.parameters()).device
    idx, z_fit = ((torch.randint(len(train_x), (cfg.batch,), generator=state.gen), None) if state.teacher is None
                  else state.teacher.draw(cfg.batch, state.gen))
    k = int(torch.randint(model_cfg.min_segments, model_cfg.max_segments + 1, (1,), generator=state.gen))
    x = augment_batch(train_x[idx].to(device).float() / 255, cfg.augment, state.gen)  # (B, 3, S, S)
    rec, kl, dec, mu = reconstruction_loss(ddp_model, x, k, sch["tau"], sample=True, supersample=cfg.supersample,
                                         pyramid=cfg.pyramid, solved=cfg.solved, detail=cfg.detail)
    loss = rec + sch["beta"] * kl
    taught = {} if z_fit is None else {"distill": distill_loss(mu, z_fit)}
    if state.outlines is not None:
        taught["outline"] = state.outlines.loss(dec.points, idx, model_cfg.image_size)
    loss = loss + sum(getattr(cfg, n) * v for n, v in taught.items())
    state.opt.zero_grad()
    loss.backward()
    gnorm = torch.nn.utils.clip_grad_norm_(state.model.parameters(), cfg.grad_clip)
    # gnorm is computed from the all-reduced gradients, so every DDP rank decides alike
    finite = bool(torch.isfinite(gnorm)) and (world > 1 or bool(torch.isfinite(loss)))
    state.step += 1
    if finite:
        state.opt.step()
        if state.ema is not None:
            state.ema.update_parameters(state.model)
    else:
        state.opt.zero_grad()
    return {"loss": loss.item(), "pyramid_l2": rec.item(), "kl": kl.item(), **{n: v.item() for n, v in taught.items()},
            "k": k, "lr": sch["lr"], "tau": sch["tau"], "grad_norm": float(gnorm), "finite": finite, "images": len(x) * world}


def validate(state: TrainState, val_x: torch.Tensor, model_cfg: ModelConfig, cfg: TrainConfig) -> Validated:
    """The ``val`` event: ``evaluate_l2`` of the exported weights (with an EMA, the raw
    weights' figures are kept under ``raw_*``)."""
    val = lambda m: evaluate_l2(m, val_x, model_cfg.segments, cfg.tau_end,  # noqa: E731
                                supersample=cfg.supersample, pyramid=cfg.pyramid, solved=cfg.solved)
    figures = val(state.model)
    if state.ema is not None:
        figures = {**figures, **{f"raw_{k}": v for k, v in figures.items()}, **val(state.exported)}
    return Validated(state.step, figures, time.time())


class _Log:
    """Events go to ``on_event`` and (rank 0) to ``RUN/metrics.jsonl``; ``train`` events carry the throughput."""

    def __init__(self, path: Path, emit: Callable[[Event], None], main: bool):
        self.path, self.emit, self.main = path, emit, main
        self.t_last, self.n_last = time.perf_counter(), 0

    def __call__(self, event: Event) -> None:
        self.emit(event)
        if self.main:
            with open(self.path, "a") as f:
                f.write(json.dumps(event.as_dict()) + "\n")

    def train(self, step: int, out: dict) -> None:
        now = time.perf_counter()
        figures = {k: v for k, v in out.items() if k not in ("finite", "images")}
        self(TrainStep(step, figures, self.n_last / max(1e-9, now - self.t_last), time.time()))
        self.t_last, self.n_last = now, 0


def _due(step: int, every: int, last: int) -> bool:
    return step % every == 0 or step == last


def train(
    data_dir: str | Path,
    run_dir: str | Path,
    model_cfg: ModelConfig,
    train_cfg: TrainConfig,
    *,
    device: torch.device = torch.device("cpu"),
    val_dir: str | Path | None = None,
    resume: bool = False,
    overwrite: bool = False,
    on_event: Callable[[Event], None] | None = None,
    images: torch.Tensor | None = None,
    epochs: float | None = None,
    init_state: dict[str, torch.Tensor] | None = None,
    minutes: float | None = None,
) -> Path:
    """Train an Im2Vec model (or the ImageVAE baseline, ``model_cfg.arch``); returns the
    exported model folder ``RUN/model``.

    Under ``torchrun`` (``WORLD_SIZE`` > 1) it runs DDP (gloo on CPU, nccl on CUDA); each rank draws its own
    batches and only rank 0 writes files. ``images`` (uint8 ``(N, 3, S, S)``) bypasses the folder loading, for
    tests. ``epochs`` overrides ``train_cfg.steps`` by passes over the training images. ``init_state`` (a state
    dict of the same config) starts from trained weights with a fresh optimiser: fine-tuning. ``minutes`` bounds
    the call (a training phase within a session): past it, the run stops at the step it reached (``TimeUp``),
    checkpoints and exports; ``resume`` goes on. A ``run_dir`` that holds a run is continued with ``resume`` or
    started over (its run files removed, the folder's other files kept) with ``overwrite``; else it is refused.
    """
    emit = on_event or (lambda e: None)
    deadline = math.inf if minutes is None else time.monotonic() + 60 * minutes
    run_dir = Path(run_dir)
    device, rank, world = setup_distributed(device)
    main = rank == 0
    model = _build(model_cfg, train_cfg, device, init_state)  # first: a bad config fails before any file changes
    if main:
        prepare_run_dir(run_dir, resume, overwrite, data_dir)
    train_x, val_x = load_splits(data_dir, val_dir, model_cfg, train_cfg, images,
                                 lambda msg: emit(Skipped(msg)) if main else None)
    if epochs:
        train_cfg = dataclasses.replace(train_cfg, steps=max(1, round(epochs * len(train_x) / train_cfg.batch)))
    emit(DataLoaded(len(train_x), len(val_x), train_cfg.steps))
    state, ckpt = TrainState.create(model, train_cfg, rank), run_dir / "checkpoint.pt"
    log = _Log(run_dir / "metrics.jsonl", emit, main)
    if resume:
        state.load(ckpt, model_cfg, rank)
        emit(Resumed(state.step))
    _auxiliary_targets(state, run_dir, train_x, train_cfg, log, rank, world)
    ddp_model = model if world == 1 else torch.nn.parallel.DistributedDataParallel(  # some heads are idle by
        model, device_ids=[device.index] if device.type == "cuda" else None, find_unused_parameters=True)  # config
    if main:
        atomic_write(run_dir / "train_config.json", train_cfg.to_json())
    _loop(state, ddp_model, train_x, val_x, model_cfg, train_cfg, run_dir, log, rank, world, deadline)
    if main:
        _export(state, train_x, str(data_dir or ""), run_dir, train_cfg, emit)
    if world > 1:
        dist.barrier()
    return run_dir / "model"


def _auxiliary_targets(state: TrainState, run_dir: Path, train_x: torch.Tensor, cfg: TrainConfig, log: _Log,
                       rank: int, world: int) -> None:
    """An outline phase's outlines (traced anew on resume); a distillation phase's teacher (kept for a resume)."""
    if cfg.outline > 0:
        state.outlines = trace_targets(train_x, lambda done, n: log(Tracing(done, n, time.time())))
    if cfg.distill > 0:
        state.teacher = load_or_fit_teacher(run_dir, state.model, train_x, cfg.distill_images, cfg.seed,
                                            lambda done, n: log(Teaching(done, n, time.time())), rank, world)


def _export(state: TrainState, train_x: torch.Tensor, data: str, run_dir: Path, cfg: TrainConfig,
            emit: Callable[[Event], None]) -> None:
    """``RUN/model``: the exported weights with their latent priors (``model.prior``, also kept
    beside ``checkpoint.pt`` for ``export``), fitted to the posterior means of the training images
    (none for fewer than ``PRIOR_MIN_IMAGES``): a Gaussian mixture of ``cfg.prior_components``
    components and the neighbour prior of ``cfg.prior_neighbours``, each fewer for a small set."""
    model = state.exported
    if len(train_x) >= PRIOR_MIN_IMAGES:
        emit(PriorFitting(len(train_x)))
        was, mu = model.training, posterior_means(model.eval(), train_x)  # (N, D)
        model.train(was)
        k = max(1, min(cfg.prior_components, len(train_x) // IMAGES_PER_COMPONENT))
        model.latent_prior = fit_prior(mu, k, seed=cfg.seed, data=data, step=state.step, shrink=cfg.prior_shrink)
        near = min(cfg.prior_neighbours, most_neighbours(len(mu)))
        model.neighbour_prior = fit_neighbours(mu, near, seed=cfg.seed, data=data, step=state.step) if near else None
        save_priors(model, run_dir)
    else:
        emit(NoPrior(len(train_x), PRIOR_MIN_IMAGES))
    save_pretrained(model, run_dir / "model")


def _build(model_cfg: ModelConfig, cfg: TrainConfig, device: torch.device, init_state: dict | None) -> torch.nn.Module:
    """The model to train, its weights frozen as ``cfg.train_only`` says."""
    for key in ("distill", "outline"):
        if getattr(cfg, key) > 0 and model_cfg.arch != "im2vec":
            raise Im2VecError(f"{key} > 0 trains the paths of an im2vec model; --arch {model_cfg.arch} has none")
    if cfg.solved and not model_cfg.solve_colors:
        raise Im2VecError("solved trains through the colour solve: it needs an im2vec model with solve_colors")
    torch.manual_seed(cfg.seed)
    try:
        model = build_model(model_cfg).to(device)
    except ValueError as exc:
        raise Im2VecError(f"model config: {exc}") from None
    if init_state is not None:
        model.load_state_dict(init_state)  # copies into the parameters, casting fp16 storage
    freeze(model, cfg.train_only)
    return model


def _loop(state: TrainState, ddp_model, train_x, val_x, model_cfg: ModelConfig, cfg: TrainConfig, run_dir: Path,
          log: _Log, rank: int, world: int, deadline: float = math.inf) -> None:
    """Steps until ``cfg.steps`` (or the ``deadline``, ``time.monotonic()``: that step is the
    last) with the periodic jobs; Ctrl-C (or SIGTERM via the CLI) checkpoints, then re-raises."""
    ckpt, main, bad_run = run_dir / "checkpoint.pt", rank == 0, 0  # bad_run: non-finite steps in a row
    state.model.train()
    log.t_last = time.perf_counter()  # the throughput counts training, not the set-up (a teacher's fit)
    with HeldSignals() as held:  # Ctrl-C and SIGTERM land between whole steps: the checkpoint resumes exactly
        try:
            while state.step < cfg.steps:
                held.deliver()
                out = train_step(state, ddp_model, train_x, model_cfg, cfg, world)
                step = state.step
                last = step if _past(deadline, step, cfg.log_every, world, state.model) else cfg.steps
                bad_run = 0 if out["finite"] else bad_run + 1
                if not out["finite"]:
                    log(NonFinite(step, out["loss"], out["grad_norm"], bad_run, time.time()))
                    if bad_run >= MAX_NONFINITE_IN_A_ROW:
                        raise TrainingError(f"the loss or gradient was not finite for {bad_run} steps in a row (up "
                                            f"to step {step}); the last good checkpoint is {ckpt}; try a lower --lr")
                log.n_last += out["images"]
                if _due(step, cfg.log_every, last):
                    log.train(step, out)
                if main and _due(step, cfg.val_every, last):
                    log(validate(state, val_x, model_cfg, cfg))
                if main and _due(step, cfg.preview_every, last):
                    atomic_write(run_dir / f"preview_{step:07d}.png",
                                 preview_grid(state.exported, val_x[:8], model_cfg.segments, cfg.tau_end))
                if _due(step, cfg.ckpt_every, last):
                    state.save(ckpt, model_cfg, cfg, rank, world)
                if last < cfg.steps:
                    log(TimeUp(step, cfg.steps, time.time()))
                    break
        except BaseException as exc:
            if not isinstance(exc, Exception):  # interrupted (not failed): the last whole step is saved
                state.save(ckpt, model_cfg, cfg, rank, world)
            raise


def _past(deadline: float, step: int, every: int, world: int, model: torch.nn.Module) -> bool:
    """Whether the ``deadline`` has passed; under DDP, on any rank, asked at logging steps only."""
    if deadline == math.inf or (world > 1 and step % every):
        return False
    past = time.monotonic() > deadline
    if world > 1:
        flag = torch.tensor([float(past)], device=next(model.parameters()).device)
        dist.all_reduce(flag, op=dist.ReduceOp.MAX)
        past = bool(flag.item())
    return past
