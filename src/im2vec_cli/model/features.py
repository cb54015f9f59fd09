"""The feature network of the sample-quality metric (``evaluate.precision_recall``).

A small CNN trained in the project on a dataset's training split: a classifier where the
data have labels (fonts: which character; MNIST: which digit), an autoencoder where they
have none (emoji, icons). Its penultimate layer is the feature space in which samples and
test images are compared (Kynkäänniemi et al., NeurIPS 2019, use a pre-trained VGG; nothing
can be downloaded here, and a network trained on the data itself sees what matters in it).

Stored like a model: ``config.json`` (``FeatureConfig``) beside ``model.safetensors``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import torch
import torch.nn.functional as F
from torch import nn

from ..config import JsonConfig
from ..errors import ModelError
from ..files import atomic_write
from ..frame import FITS

WORK_SIZE = 32  # every input is average-pooled to this size first


@dataclass(frozen=True)
class FeatureConfig(JsonConfig):
    """``image_size`` and ``fit``: the frame the inputs come in (the dataset's model's);
    ``classes``: the label names, the last one ``train_features.JUNK`` (empty: an autoencoder)."""

    image_size: int = 64
    fit: str = "resize"
    width: int = 32
    feature: int = 128
    classes: list = field(default_factory=list)
    data: str = ""
    test_accuracy: float = -1.0  # on the test split (classifiers); -1: not measured
    test_mse: float = -1.0  # reconstruction MSE on the test split (autoencoders)

    def __post_init__(self):
        if self.image_size < WORK_SIZE or self.image_size % WORK_SIZE:
            raise ModelError(f"FeatureConfig.image_size must be a multiple of {WORK_SIZE}, got {self.image_size}")
        if self.fit not in FITS:
            raise ModelError(f"FeatureConfig.fit must be one of {FITS}, got {self.fit!r}")


class FeatureNet(nn.Module):
    """``(B, 3, S, S)`` in [0, 1] -> features ``(B, F)``; ``logits`` (classifier) or
    ``reconstruct`` (autoencoder, ``(B, 3, 32, 32)``) for training."""

    def __init__(self, config: FeatureConfig):
        super().__init__()
        self.config = config
        w = config.width
        layers, c_in = [], 3
        for c in (w, 2 * w, 4 * w):  # 32 -> 16 -> 8 -> 4
            layers += [nn.Conv2d(c_in, c, 3, 1, 1), nn.GroupNorm(8, c), nn.SiLU(),
                       nn.Conv2d(c, c, 3, 2, 1), nn.GroupNorm(8, c), nn.SiLU()]
            c_in = c
        self.net = nn.Sequential(*layers)
        self.proj = nn.Sequential(nn.Flatten(), nn.Linear(4 * w * 16, config.feature), nn.SiLU())
        if config.classes:
            self.head = nn.Linear(config.feature, len(config.classes))
        else:
            self.head = nn.Sequential(  # 4 -> 32, mirror of the encoder
                nn.Linear(config.feature, 4 * w * 16), nn.Unflatten(1, (4 * w, 4, 4)),
                nn.ConvTranspose2d(4 * w, 2 * w, 4, 2, 1), nn.SiLU(),
                nn.ConvTranspose2d(2 * w, w, 4, 2, 1), nn.SiLU(),
                nn.ConvTranspose2d(w, 3, 4, 2, 1))

    @property
    def is_classifier(self) -> bool:
        return bool(self.config.classes)

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        s = self.config.image_size
        if images.dim() != 4 or images.shape[1:] != (3, s, s):
            raise ValueError(f"images must be (B, 3, {s}, {s}), got {tuple(images.shape)}")
        x = F.adaptive_avg_pool2d(images.float(), WORK_SIZE)  # (B, 3, 32, 32)
        return self.proj(self.net(2 * x - 1))  # (B, F)

    def logits(self, images: torch.Tensor) -> torch.Tensor:
        """Class scores ``(B, K)`` (classifiers only)."""
        if not self.is_classifier:
            raise ValueError("an autoencoder feature net has no classes")
        return self.head(self(images))

    def reconstruct(self, images: torch.Tensor) -> torch.Tensor:
        """Reconstruction ``(B, 3, 32, 32)`` in [0, 1] (autoencoders only)."""
        if self.is_classifier:
            raise ValueError("a classifier feature net does not reconstruct")
        return torch.sigmoid(self.head(self(images)))

    def save(self, folder: str | Path) -> Path:
        from safetensors.torch import save

        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        state = {k: v.detach().cpu().contiguous() for k, v in self.state_dict().items()}
        atomic_write(folder / "model.safetensors", save(state, metadata={"format": "pt"}))
        atomic_write(folder / "config.json", self.config.to_json())
        return folder

    @classmethod
    def load(cls, folder: str | Path, device: str | torch.device = "cpu") -> FeatureNet:
        from safetensors import SafetensorError
        from safetensors.torch import load_file

        folder = Path(folder)
        if not (folder / "config.json").is_file():
            raise ModelError(f"{folder}: not a feature net folder (no config.json)")
        net = cls(FeatureConfig.load(folder / "config.json"))
        try:
            net.load_state_dict(load_file(str(folder / "model.safetensors")), strict=True)
        except (SafetensorError, OSError, RuntimeError) as exc:
            raise ModelError(f"{folder}/model.safetensors: unreadable feature net ({str(exc).splitlines()[0]})") from None
        return net.to(device).eval()
