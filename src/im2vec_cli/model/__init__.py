"""The models: Im2Vec (paper sec. 3) and the ImageVAE baseline (sec. 4), their losses, and
exported model folders (``pretrained.py``). Nothing here imports ``data/``."""

from torch import nn

from ..config import ModelConfig
from ..frame import check_fit
from .imagevae import ImageVAE
from .vae import Decoded, Im2Vec


def build_model(config: ModelConfig) -> nn.Module:
    """The model ``config.arch`` names: ``Im2Vec`` or the ``ImageVAE`` baseline."""
    check_fit(config.fit)
    if config.arch == "im2vec":
        return Im2Vec(config)
    if config.arch == "imagevae":
        return ImageVAE(config)
    raise ValueError(f"arch must be 'im2vec' or 'imagevae', got {config.arch!r}")


def flatten_rnns(model: nn.Module) -> None:
    """Gather each LSTM's weights into one cuDNN buffer again (a no-op on the CPU). A deepcopy of
    a model (the training EMA's) holds them as separate tensors, which cuDNN would copy, with a
    warning, at every call."""
    for m in model.modules():
        if isinstance(m, nn.RNNBase):
            m.flatten_parameters()


__all__ = ["Decoded", "ImageVAE", "Im2Vec", "build_model", "flatten_rnns"]
