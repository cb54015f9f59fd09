"""Distillation: the encoder taught the latents that ``project`` fits (issue 37).

The encoder's guess ``z = mu`` draws held-out glyphs with 12x the raster baseline's error,
where the latent fitted by ``project.LATENT`` (30 Adam steps through the renderer from that
guess) draws them with 3.9x (docs/results/fonts-ablation.md): an amortisation gap (Cremer et
al. 2018), not a decoder that cannot draw them. A training phase with
``TrainConfig.distill > 0`` closes it:

1. ``fit_teacher``: before the first step, the latents of ``distill_images`` training images
   are fitted with the starting weights (the ``Teacher``); they are kept in
   ``RUN/teacher.safetensors``, so a resumed run learns the same targets;
2. each step draws its batch from those images and adds ``distill`` times the mean squared
   distance of ``mu`` to their fitted latents (``distill_loss``) to the usual loss;
3. ``TrainConfig.train_only = "encoder"`` (``freeze``) keeps the decoder the latents were
   fitted to.

The targets come from our renderer and the pictures alone: still no vector supervision.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import torch
import torch.distributed as dist

from ..checkpoint import TEACHER_FILE
from ..errors import Im2VecError
from ..files import atomic_write
from ..project import LATENT, project_frames

TEACHER_BATCH = 64  # pictures fitted at once

__all__ = ["TEACHER_FILE", "Teacher", "distill_loss", "fit_teacher", "freeze", "load_or_fit_teacher"]


@dataclass
class Teacher:
    """Fitted latents ``z (T, D)`` of the training images ``index (T,)`` (rows of the training set)."""

    index: torch.Tensor
    z: torch.Tensor

    def draw(self, batch: int, gen: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
        """A random batch: training-set rows ``(B,)`` and their fitted latents ``(B, D)``."""
        j = torch.randint(len(self.index), (batch,), generator=gen)
        return self.index[j], self.z[j]

    def save(self, path: Path) -> None:
        from safetensors.torch import save

        atomic_write(path, save({"index": self.index.contiguous(), "z": self.z.contiguous()}))

    @classmethod
    def load(cls, path: Path) -> Teacher:
        from safetensors import SafetensorError
        from safetensors.torch import load_file

        try:
            t = load_file(str(path))
            return cls(t["index"].long(), t["z"].float())
        except (OSError, KeyError, SafetensorError) as exc:
            raise Im2VecError(f"{path}: not a teacher file ({exc})") from None


def fit_teacher(model: torch.nn.Module, train_x: torch.Tensor, images: int, seed: int,
                on_progress: Callable[[int, int], None] | None = None, rank: int = 0, world: int = 1) -> Teacher:
    """The latents ``project.LATENT`` fits to ``images`` training images (a seeded subset of
    ``train_x``, uint8 ``(N, 3, S, S)``; all of them when there are fewer), ``TEACHER_BATCH`` at
    a time. Under DDP (``world`` > 1) rank ``r`` fits batches ``r, r + world, ...`` and the ranks
    gather the whole teacher, the same batches as one process fits (``on_progress`` counts its own)."""
    gen = torch.Generator().manual_seed(seed)
    index = torch.randperm(len(train_x), generator=gen)[:images].sort().values
    batches = list(torch.split(index, TEACHER_BATCH))[rank::world]
    dev = next(model.parameters()).device
    was = model.training
    model.eval()
    zs, done, mine = [], 0, sum(len(b) for b in batches)
    try:
        for rows in batches:
            batch = train_x[rows].to(dev).float() / 255  # (b, 3, S, S): the model's frame
            zs.append(project_frames(model, batch, LATENT).z.detach().cpu())
            done += len(rows)
            if on_progress is not None:
                on_progress(done, mine)
    finally:
        model.train(was)
    if world > 1:
        shares: list = [None] * world
        dist.all_gather_object(shares, zs)  # shares[r]: rank r's batches, in order
        zs = [shares[i % world][i // world] for i in range(sum(len(s) for s in shares))]
    return Teacher(index, torch.cat(zs))


def load_or_fit_teacher(run_dir: Path, model: torch.nn.Module, train_x: torch.Tensor, images: int, seed: int,
                        on_progress: Callable[[int, int], None] | None = None, rank: int = 0,
                        world: int = 1) -> Teacher:
    """``RUN/teacher.safetensors`` when it is there (a resumed run), else ``fit_teacher`` (the
    ranks share the fit; rank 0 saves it there)."""
    path = Path(run_dir) / TEACHER_FILE
    if world > 1:
        dist.barrier()  # rank 0 has prepared the run folder: every rank sees the same files
    if path.is_file():
        teacher = Teacher.load(path)
        if len(teacher.index) == 0 or int(teacher.index.max()) >= len(train_x):
            raise Im2VecError(f"{path}: its images are not this run's training images")
        return teacher
    teacher = fit_teacher(model, train_x, images, seed, on_progress, rank, world)
    if rank == 0:
        teacher.save(path)
    return teacher


def distill_loss(mu: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
    """Mean squared distance ``mu (B, D)`` to the fitted latents ``z (B, D)``, per latent dimension."""
    return (mu - z.to(mu)).square().mean()


def freeze(model: torch.nn.Module, train_only: str) -> None:
    """``train_only="encoder"``: every weight but the encoder's stops learning; ``""``: all learn."""
    for name, p in model.named_parameters():
        p.requires_grad_(not train_only or name.startswith(f"{train_only}."))
