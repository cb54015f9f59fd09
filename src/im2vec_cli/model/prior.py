"""Ex-post latent density: where ``sample`` draws its latents from.

A VAE trained with a small KL weight (ours: ``beta`` ~1e-6 on the sum over 128 dimensions)
leaves its posterior codes far from N(0, I), so decoding prior draws gives shapes the
decoder never saw. Following Ghosh et al., "From Variational to Deterministic
Autoencoders" (ICLR 2020, ex-post density estimation), a Gaussian mixture with full
covariances is fitted to the posterior means of the training images once the model is
trained, and stored beside the weights:

    latent_prior.safetensors   weights (K,), means (K, D), scale_tril (K, D, D) (Cholesky
                               factors of the covariances), float32
    latent_prior.json          LatentPriorConfig: components, latent size, how it was fitted

``temperature`` scales every component's standard deviation (T = 1: the fitted density;
T = 0: the component means), as it scales N(0, I) for ``prior="normal"``. A prior stores the
temperature ``sample`` uses by default (``LatentPriorConfig.temperature``: 1 as fitted; a lower
one chosen on the validation split by ``bench/research/prior_temperature.py`` trades recall for precision,
the truncation of Brock et al. 2019).

The training latents lie on thin sheets, and a mixture's draws fall between them, where the
decoder draws blobs. ``NeighbourPrior`` (what ``sample`` prefers) keeps training latents and
draws on the segments between near neighbours among them:

    latent_neighbours.safetensors   anchors (N, D) float16 (up to MAX_ANCHORS training latents),
                                    neighbours (N, k) int32 (each anchor's k nearest others)
    latent_neighbours.json          NeighbourPriorConfig: k, the images and seed they came from
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from ..config import DEFAULT_COMPONENTS, DEFAULT_NEIGHBOURS, DEFAULT_SHRINK, JsonConfig
from ..errors import ModelError
from ..files import atomic_write

PRIOR_WEIGHTS = "latent_prior.safetensors"
PRIOR_CONFIG = "latent_prior.json"
NEIGHBOURS_WEIGHTS = "latent_neighbours.safetensors"
NEIGHBOURS_CONFIG = "latent_neighbours.json"
MAX_ANCHORS = 4096  # training latents a neighbour prior keeps (seeded subset): 1 MB in fp16 at D = 128
IMAGES_PER_COMPONENT = 30  # a mixture fitted at the end of training has at most N / this components
# (emoji: 100 components of 3,126 latents, shrunk by 0.05, score best on the validation split)


@dataclass(frozen=True)
class LatentPriorConfig(JsonConfig):
    """What a stored prior is: its size, and the data and step it was fitted on (provenance)."""

    components: int = DEFAULT_COMPONENTS
    latent: int = 128
    covariance: str = "full"
    images: int = 0  # training images whose posterior means were fitted
    data: str = ""  # the folder they came from
    seed: int = 0
    step: int = -1  # the training step of the weights it was fitted to (-1: not from a run)
    log_likelihood: float = 0.0  # mean per image, of the fitted latents (nats)
    shrink: float = DEFAULT_SHRINK  # added to each covariance's diagonal, in units of the latents' mean variance
    temperature: float = 1.0  # what ``sample`` draws with unless told (chosen on the validation split)

    def __post_init__(self):
        if not 0 <= self.temperature <= 4:  # also refuses NaN
            raise ValueError(f"temperature must be in [0, 4], got {self.temperature}")


class LatentPrior:
    """A Gaussian mixture over latents ``(D,)``: ``weights (K,)``, ``means (K, D)``,
    ``scale_tril (K, D, D)`` lower-triangular with a positive diagonal."""

    def __init__(self, weights: torch.Tensor, means: torch.Tensor, scale_tril: torch.Tensor,
                 config: LatentPriorConfig | None = None):
        k, d = means.shape
        if weights.shape != (k,) or scale_tril.shape != (k, d, d):
            raise ValueError(f"prior shapes disagree: weights {tuple(weights.shape)}, means {tuple(means.shape)}, "
                             f"scale_tril {tuple(scale_tril.shape)}")
        self.weights = weights.double() / weights.double().sum()
        self.means, self.scale_tril = means.float(), scale_tril.float()
        self.config = config or LatentPriorConfig(components=k, latent=d)

    @property
    def latent(self) -> int:
        return self.means.shape[1]

    def sample(self, n: int, *, seed: int = 0, temperature: float | None = None) -> torch.Tensor:
        """``n`` latents ``(n, D)`` float32, the same for the same ``seed`` (its own generator);
        ``temperature`` ``None``: the stored one (``config.temperature``)."""
        temperature = self.config.temperature if temperature is None else temperature
        g = torch.Generator().manual_seed(seed)
        comp = torch.multinomial(self.weights, n, replacement=True, generator=g)  # (n,)
        eps = torch.randn(n, self.latent, 1, generator=g)  # (n, D, 1)
        return self.means[comp] + temperature * (self.scale_tril[comp] @ eps).squeeze(-1)  # (n, D)

    def log_prob(self, z: torch.Tensor) -> torch.Tensor:
        """Log density of latents ``(N, D)`` -> ``(N,)`` (float64)."""
        mix = torch.distributions.MixtureSameFamily(
            torch.distributions.Categorical(probs=self.weights),
            torch.distributions.MultivariateNormal(self.means.double(), scale_tril=self.scale_tril.double()))
        return mix.log_prob(z.double())

    def save(self, folder: str | Path) -> Path:
        """Write ``latent_prior.safetensors`` and ``latent_prior.json`` into ``folder`` (atomically)."""
        tensors = {"weights": self.weights.float(), "means": self.means, "scale_tril": self.scale_tril}
        return _save(Path(folder), PRIOR_WEIGHTS, tensors, PRIOR_CONFIG, self.config)

    @classmethod
    def load(cls, folder: str | Path) -> LatentPrior | None:
        """The prior stored in a model folder, or ``None`` when it has none; ``ModelError``
        when it is there but unreadable or does not fit."""
        path = Path(folder) / PRIOR_WEIGHTS
        prior = _load(Path(folder), PRIOR_WEIGHTS, PRIOR_CONFIG, LatentPriorConfig, "latent prior",
                      lambda t, cfg: cls(t["weights"], t["means"], t["scale_tril"], cfg))
        if prior is None:
            return None
        if not all(torch.isfinite(v).all() for v in (prior.weights, prior.means, prior.scale_tril)):
            raise ModelError(f"{path}: latent prior contains NaN or infinite values")
        if (prior.scale_tril.diagonal(dim1=1, dim2=2) <= 0).any():
            raise ModelError(f"{path}: latent prior covariance factors are not positive definite")
        return prior


def _save(folder: Path, weights: str, tensors: dict[str, torch.Tensor], config: str, cfg: JsonConfig) -> Path:
    """``folder/weights`` (safetensors) and ``folder/config`` (JSON), each written atomically."""
    from safetensors.torch import save

    atomic_write(folder / weights, save({k: v.contiguous() for k, v in tensors.items()}, metadata={"format": "pt"}))
    atomic_write(folder / config, cfg.to_json())
    return folder / weights


def _load(folder: Path, weights: str, config: str, cfg_cls: type[JsonConfig], what: str, build):
    """``build(tensors, config)`` from ``folder/weights`` and ``folder/config``, or ``None`` when the
    folder has no ``weights``; ``ModelError`` naming ``what`` when either is unreadable."""
    from safetensors import SafetensorError
    from safetensors.torch import load_file

    path = folder / weights
    if not path.is_file():
        return None
    try:
        cfg = cfg_cls.load(folder / config)
        return build(load_file(str(path)), cfg)
    except (SafetensorError, OSError, ValueError, KeyError, json.JSONDecodeError) as exc:
        raise ModelError(f"{path}: unreadable {what} ({str(exc).splitlines()[0]})") from None


def fit_prior(latents: torch.Tensor, components: int = DEFAULT_COMPONENTS, *, seed: int = 0, data: str = "",
              step: int = -1, shrink: float = DEFAULT_SHRINK) -> LatentPrior:
    """A full-covariance Gaussian mixture fitted to latents ``(N, D)`` by EM (scikit-learn's
    ``GaussianMixture``, k-means++ start); ``shrink`` is added to every covariance's diagonal, in
    units of the latents' mean variance, so a component on few points stays well-conditioned
    (and, larger, spreads to the latents of pictures like its own: chosen on the validation
    split by ``bench/research/prior_components.py``)."""
    from sklearn.mixture import GaussianMixture

    if latents.dim() != 2:
        raise ValueError(f"latents must be (N, D), got {tuple(latents.shape)}")
    n, d = latents.shape
    if not 1 <= components <= max(1, n // 2):
        raise ValueError(f"components must be in [1, max(1, N/2)] = [1, {max(1, n // 2)}], got {components}")
    if not (np.isfinite(shrink) and shrink >= 0):
        raise ValueError(f"shrink must be a finite number >= 0, got {shrink}")
    x = latents.double().numpy()
    scale = float(x.var(0).mean())
    gm = GaussianMixture(components, covariance_type="full", reg_covar=shrink * scale, random_state=seed,
                         init_params="k-means++", max_iter=100, tol=1e-2)  # tol: nats per image
    gm.fit(x)
    cfg = LatentPriorConfig(components=components, latent=d, images=n, data=data, seed=seed, step=step,
                            log_likelihood=float(gm.score(x)), shrink=shrink)
    tril = np.linalg.cholesky(gm.covariances_)  # (K, D, D)
    return LatentPrior(torch.from_numpy(gm.weights_), torch.from_numpy(gm.means_), torch.from_numpy(tril), cfg)


@torch.no_grad()
def posterior_means(model: torch.nn.Module, images: torch.Tensor, batch: int = 256) -> torch.Tensor:
    """The encoder's means ``(N, D)`` of ``images (N, 3, S, S)`` (uint8, or float in [0, 1]) at the model size."""
    dev = next(model.parameters()).device
    out = []
    for i in range(0, len(images), batch):
        x = images[i : i + batch]
        x = x.float() / 255 if x.dtype == torch.uint8 else x.float()
        out.append(model.encode(x.to(dev))[0].float().cpu())
    return torch.cat(out)


@dataclass(frozen=True)
class NeighbourPriorConfig(JsonConfig):
    """What a stored neighbour prior is: its anchors, their neighbours, how it was made."""

    anchors: int = 0  # training latents kept (all, or a seeded subset of MAX_ANCHORS)
    latent: int = 128
    neighbours: int = DEFAULT_NEIGHBOURS  # k: each anchor's nearest anchors a draw may step towards
    images: int = 0  # training images encoded
    data: str = ""
    seed: int = 0
    step: int = -1  # the training step of the weights it was fitted to (-1: not from a run)
    temperature: float = 1.0  # what ``sample`` draws with unless told

    def __post_init__(self):
        if not 0 <= self.temperature <= 4:  # also refuses NaN
            raise ValueError(f"temperature must be in [0, 4], got {self.temperature}")


class NeighbourPrior:
    """Latents between training pictures that look alike: ``anchors (N, D)``, the posterior
    means of (a subset of) the training images, and ``neighbours (N, k)``, each anchor's k
    nearest other anchors (Euclidean, in the latent space).

    A draw picks an anchor ``a`` and one of its neighbours ``b`` uniformly and returns
    ``a + u (b - a)``, ``u`` uniform in ``[0, temperature / 2]``: at temperature 1 anywhere from
    the anchor to the midpoint (so, over both ends, the whole segment), at 0 the training
    latents themselves. A Gaussian mixture's draws (``LatentPrior``) fall between the thin sheets
    the training latents lie on, where the decoder draws blobs; these stay on segments between
    neighbours, where it draws what its training pictures look like (mixtures of two close
    ones: their nearest-training-picture distance is reported beside the precision)."""

    def __init__(self, anchors: torch.Tensor, neighbours: torch.Tensor, config: NeighbourPriorConfig | None = None):
        n, d = anchors.shape
        if neighbours.dim() != 2 or len(neighbours) != n or neighbours.shape[1] < 1:
            raise ValueError(f"neighbours must be (N, k >= 1) with N = {n}, got {tuple(neighbours.shape)}")
        if neighbours.min() < 0 or neighbours.max() >= n:
            raise ValueError(f"neighbour indices must be in [0, {n})")
        self.anchors, self.neighbours = anchors.float(), neighbours.long()
        self.config = config or NeighbourPriorConfig(anchors=n, latent=d, neighbours=neighbours.shape[1])

    @property
    def latent(self) -> int:
        return self.anchors.shape[1]

    def sample(self, n: int, *, seed: int = 0, temperature: float | None = None) -> torch.Tensor:
        """``n`` latents ``(n, D)`` float32, the same for the same ``seed`` (its own generator)."""
        temperature = self.config.temperature if temperature is None else temperature
        g = torch.Generator().manual_seed(seed)
        a = torch.randint(len(self.anchors), (n,), generator=g)
        b = self.neighbours[a, torch.randint(self.neighbours.shape[1], (n,), generator=g)]
        u = torch.rand(n, 1, generator=g) * (temperature / 2)
        return self.anchors[a] + u * (self.anchors[b] - self.anchors[a])

    def save(self, folder: str | Path) -> Path:
        """Write ``latent_neighbours.safetensors`` (anchors fp16) and ``.json`` into ``folder`` (atomically)."""
        tensors = {"anchors": self.anchors.half(), "neighbours": self.neighbours.int()}
        return _save(Path(folder), NEIGHBOURS_WEIGHTS, tensors, NEIGHBOURS_CONFIG, self.config)

    @classmethod
    def load(cls, folder: str | Path) -> NeighbourPrior | None:
        """The neighbour prior stored in a model folder, or ``None``; ``ModelError`` when unreadable."""
        path = Path(folder) / NEIGHBOURS_WEIGHTS
        prior = _load(Path(folder), NEIGHBOURS_WEIGHTS, NEIGHBOURS_CONFIG, NeighbourPriorConfig, "neighbour prior",
                      lambda t, cfg: cls(t["anchors"], t["neighbours"], cfg))
        if prior is None:
            return None
        if not torch.isfinite(prior.anchors).all():
            raise ModelError(f"{path}: neighbour prior contains NaN or infinite values")
        return prior


def most_neighbours(images: int) -> int:
    """The largest k a neighbour prior of ``images`` training images can have: one fewer than the anchors it keeps."""
    return min(images, MAX_ANCHORS) - 1


def anchor_rows(n: int, seed: int = 0, max_anchors: int = MAX_ANCHORS) -> torch.Tensor:
    """The rows of ``n`` latents a neighbour prior keeps: a seeded subset of ``max_anchors``
    (all when fewer), in order."""
    return torch.randperm(n, generator=torch.Generator().manual_seed(seed))[:max_anchors].sort().values


def fit_neighbours(latents: torch.Tensor, neighbours: int = DEFAULT_NEIGHBOURS, *, seed: int = 0, data: str = "",
                   step: int = -1, max_anchors: int = MAX_ANCHORS, images: int | None = None) -> NeighbourPrior:
    """A ``NeighbourPrior`` on latents ``(N, D)``: the rows ``anchor_rows`` keeps, each with its
    ``neighbours`` nearest others among them. ``images``: the latents are already those rows of
    this many images (encoding only them gives the same prior)."""
    if latents.dim() != 2:
        raise ValueError(f"latents must be (N, D), got {tuple(latents.shape)}")
    n, d = latents.shape
    if not 1 <= neighbours < min(n, max_anchors):
        raise ValueError(f"neighbours must be in [1, {min(n, max_anchors) - 1}], got {neighbours}")
    if images is not None and n != min(images, max_anchors):  # anchor_rows keeps that many
        raise ValueError(f"{n} latents are not the anchors of {images} images")
    anchors = latents[anchor_rows(n, seed, max_anchors)].half().float()  # as stored: draws are the same after saving
    dist = torch.cdist(anchors, anchors)  # (N', N'): 64 MB at N' = 4096
    dist.fill_diagonal_(float("inf"))
    near = dist.topk(neighbours, largest=False).indices  # (N', k)
    cfg = NeighbourPriorConfig(anchors=len(anchors), latent=d, neighbours=neighbours, images=images or n, data=data,
                               seed=seed, step=step)
    return NeighbourPrior(anchors, near, cfg)
