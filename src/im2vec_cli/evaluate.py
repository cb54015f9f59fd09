"""Metrics. Reconstruction L2 (paper Table 1): the mean squared error on [0, 1] pixels between
each test image and its vector reconstruction, rendered by cairosvg at the image's own size
(the SVG a user gets, in the input's frame, not the soft training render). MNIST is thus
measured at 28 x 28 although its model works at 32 x 32.

Generation and interpolation (paper Table 2): decoded images are rendered by cairosvg at the
model size and scored by the MSE to their nearest training image (fitted to the model size
the way training sees it), so a model that only reproduces its training set scores 0 and
one that draws nothing like it scores high.

Against true outlines (fonts: ``name.svg`` beside ``name.png``): IoU of the insides at 4x
(cairosvg renders thresholded at 0.5) and the symmetric Chamfer distance between the two
outlines in input pixels. Compactness: paths and cubic segments per image.

The ImageVAE baseline (paper sec. 4) draws pixels: its reconstruction is its raster output
mapped back to the input's frame, its generated images are its raster outputs, and it has no
vector metrics.

The segments ablation (paper Fig. 5): reconstruction L2 of one model decoded at each k, with
the sample deformation on, or switched off at inference (``segments_sweep``)."""

from __future__ import annotations

import io
from collections.abc import Callable
from contextlib import contextmanager, nullcontext
from pathlib import Path

import numpy as np
import torch

from .data.folder import list_images, split_dir
from .errors import DataError, Im2VecError, InputError
from .files import load_image
from .frame import fit_square, resize_square
from .infer import (
    STORED_PRIORS,
    decode,
    encode,
    lerp_latents,
    prior_latents,
    reconstruct_raster,
    resolve_prior,
    sample_temperature,
    stored_prior,
    vectorize,
)
from .model.vae import Im2Vec
from .project import project
from .raster import compiling, cubic_at, segment_controls
from .vector import VectorImage, from_svg, rasterize_svg, to_svg


def reconstruction_l2(
    model: Im2Vec, files: list[Path], *, segments: int | str | None = None, batch: int = 64, outlines: bool = True,
    on_skip: Callable[[str], None] | None = None, fit: bool = False,
) -> dict[str, float]:
    """Mean and standard error of the per-image MSE over ``files`` (unreadable files skipped,
    counted in ``images_skipped`` and told to ``on_skip``), the mean paths and segments per
    image, and, for images with their true outline beside them (``name.svg``, as the Fonts
    dataset has), IoU at 4x and the Chamfer distance (px); outlines the SVG reader does not
    take are counted in ``outlines_unread`` (and told to ``on_skip``).
    For the ImageVAE baseline: the MSE only. ``outlines=False`` skips the outline metrics.
    ``fit``: the model's paths fitted to each image (``project.project``, what ``interpolate``
    draws) instead of the encoder's guess (what ``vectorize --no-refine --parts model`` writes)."""
    if fit and (model.raster_output or segments == "auto"):
        raise ValueError("fit takes a vector model and a fixed segment count")
    skip = on_skip or (lambda msg: None)
    errs, paths, segs, ious, chamfers, unread, skipped = [], [], [], [], [], 0, 0
    for i in range(0, len(files), batch):
        imgs, names = [], []
        for f in files[i : i + batch]:
            try:
                imgs.append(load_image(f))  # (3, H, W)
                names.append(Path(f))
            except InputError as exc:
                skipped += 1
                skip(str(exc))
                continue
        if not imgs:
            continue
        if model.raster_output:
            errs += [float(((r - img) ** 2).mean()) for r, img in zip(reconstruct_raster(model, imgs), imgs)]
            continue
        for f, img, vec in zip(names, imgs, _reconstructed(model, imgs, segments, fit)):
            h, w = img.shape[1:]
            errs.append(float(((_render(vec, w, h) - img) ** 2).mean()))
            paths.append(vec.num_paths)
            segs.append(vec.num_segments)
            truth = f.with_suffix(".svg")
            if outlines and truth.is_file():
                try:
                    ref = from_svg(truth.read_bytes())
                except InputError as exc:  # an outline the reader refuses (e.g. gradients, clip paths)
                    unread += 1
                    skip(f"the outline {truth}: {exc}")
                    continue
                ious.append(outline_iou(svg_mask(to_svg(vec), 4 * w, 4 * h), svg_mask(to_svg(ref), 4 * w, 4 * h)))
                chamfers.append(chamfer_px(vec, ref))
    if not errs:
        raise DataError("no readable test images")
    out = {**mean_stderr("recon_l2", errs), "images": len(errs)}
    if paths:
        out.update(paths=float(np.mean(paths)), segments=float(np.mean(segs)))
    if ious:
        out.update(mean_stderr("outline_iou", ious), **mean_stderr("chamfer_px", chamfers), outlines=len(ious))
    if unread:
        out["outlines_unread"] = unread
    if skipped:
        out["images_skipped"] = skipped
    return out


def _reconstructed(model: Im2Vec, images: list[torch.Tensor], segments, fit: bool) -> list[VectorImage]:
    """The vector reconstructions of a batch: the encoder's guess, or the paths fitted to each image."""
    if not fit:
        return vectorize(model, images, segments=segments)
    with compiling(False):  # eager: a compile per batch shape costs more than the fit
        return project(model, images, segments=segments).in_pictures(model, images)


def mean_stderr(key: str, values: list[float]) -> dict[str, float]:
    """``{key: mean, key_stderr: standard error of the mean}`` of ``values`` (stderr 0 for one value)."""
    e = np.asarray(values, dtype=np.float64)
    return {key: float(e.mean()), key + "_stderr": float(e.std(ddof=1) / np.sqrt(len(e))) if len(e) > 1 else 0.0}


def outline_points(image: VectorImage, spacing: float = 0.25) -> np.ndarray:
    """Points along every contour of ``image`` about ``spacing`` px apart: ``(N, 2)`` pixel frame."""
    pts = []
    for shape in image.shapes:
        for c in shape.contours:
            for ctrl in segment_controls(torch.from_numpy(np.asarray(c, dtype=np.float64))).numpy():  # (S, 4, 2)
                n = max(2, int(np.ceil(np.abs(np.diff(ctrl, axis=0)).sum() / spacing)))
                pts.append(cubic_at(ctrl, np.linspace(0, 1, n, endpoint=False)))
    return np.concatenate(pts) if pts else np.zeros((0, 2))


def chamfer_px(a: VectorImage, b: VectorImage, spacing: float = 0.25) -> float:
    """Symmetric Chamfer distance between two outlines in pixels: the mean over both
    directions of each outline point's distance to the other outline (inf if one is empty)."""
    pa, pb = outline_points(a, spacing), outline_points(b, spacing)
    if not len(pa) or not len(pb):
        return float("inf")
    ta, tb = torch.from_numpy(pa), torch.from_numpy(pb)
    d = torch.cdist(ta, tb, compute_mode="donot_use_mm_for_euclid_dist")  # (Na, Nb), exact
    return float(0.5 * (d.min(1).values.mean() + d.min(0).values.mean()))


def svg_mask(text: str | bytes, width: int, height: int | None = None) -> np.ndarray:
    """Inside of an SVG's filled shapes: cairosvg render at ``width x height``, darker than 0.5.

    Returns:
        ``(H, W)`` bool. Dark-on-light drawings (glyphs) only: the colour itself is ignored.
    """
    return rasterize_svg(text, width, height or width).mean(-1) < 0.5


def outline_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two bool masks of the same shape (1.0 when both are empty)."""
    if a.shape != b.shape:
        raise ValueError(f"masks differ in shape: {a.shape} vs {b.shape}")
    union = np.logical_or(a, b).sum()
    return 1.0 if union == 0 else float(np.logical_and(a, b).sum() / union)


def eval_files(folder: str | Path, limit: int | None = None, seed: int = 0,
               on_skip: Callable[[str], None] | None = None) -> list[Path]:
    """Images under ``folder`` (``folder/test`` when present), a seeded subset of ``limit``;
    names that are not regular files are told to ``on_skip`` (``list_images``)."""
    files = list_images(split_dir(folder, "test"), on_skip)
    if limit is not None and len(files) > limit:
        g = torch.Generator().manual_seed(seed)
        files = [files[i] for i in sorted(torch.randperm(len(files), generator=g)[:limit].tolist())]
    return files


def _render(image, width: int, height: int) -> torch.Tensor:
    """A vector image -> ``(3, H, W)`` float cairosvg render (of the SVG a user gets)."""
    return torch.from_numpy(rasterize_svg(to_svg(image, 3), width, height)).permute(2, 0, 1).float()


@torch.no_grad()
def decoded_images(model, z: torch.Tensor, segments: int | None = None, chunk: int = 256) -> torch.Tensor:
    """Latents ``(N, D)`` -> ``(N, 3, S, S)`` images at the model size: cairosvg renders of the
    decoded SVGs as ``sample`` writes them (clean outlines), or the ImageVAE baseline's raster
    output."""
    if not model.raster_output:
        return torch.stack([_render(v, model.config.image_size, model.config.image_size)
                            for v in decode(model, z, segments=segments, clean=True)])
    dev = next(model.parameters()).device
    return torch.cat([model.decode(z[i : i + chunk].to(dev)).cpu() for i in range(0, len(z), chunk)]).clamp(0, 1)


@contextmanager
def deformation_off(model: Im2Vec):
    """Within the block, decode on evenly spaced circle samples (no sample deformation)."""
    saved = model.decoder.deform
    model.decoder.deform = None
    try:
        yield model
    finally:
        model.decoder.deform = saved


def segments_sweep(model: Im2Vec, files: list[Path], ks: list[int], *, deform: bool = True) -> list[dict]:
    """Paper Fig. 5: reconstruction L2 (as ``reconstruction_l2``) with every path at k segments,
    for each k in ``ks``; ``deform=False`` switches the sample deformation off at inference
    (a model trained without it, ``deform: false``, is the training-time ablation)."""
    if model.raster_output:
        raise ValueError("the ImageVAE baseline has no segments")
    if not deform and model.decoder.deform is None:
        raise ValueError("this model has no sample deformation to switch off")
    rows = []
    for k in ks:
        with nullcontext() if deform else deformation_off(model):
            r = reconstruction_l2(model, files, segments=k, outlines=False)
        rows.append({"k": k, "recon_l2": r["recon_l2"], "recon_l2_stderr": r["recon_l2_stderr"]})
    return rows


def nearest_mse(queries: torch.Tensor, references: torch.Tensor, chunk: int = 2048) -> torch.Tensor:
    """MSE from each query image to its nearest reference image.

    Args:
        queries: ``(Q, C, H, W)`` float in [0, 1].
        references: ``(R, C, H, W)`` uint8 or float in [0, 1] (uint8 keeps big sets small).

    Returns:
        ``(Q,)`` minimum over the references of the per-pixel mean squared error.
    """
    if queries.shape[1:] != references.shape[1:]:
        raise ValueError(f"queries {tuple(queries.shape[1:])} and references {tuple(references.shape[1:])} differ")
    q = queries.flatten(1).float()  # (Q, D); float32 is exact enough: errors ~1e-7 in MSE
    d = q.shape[1]
    q2 = q.square().sum(1, keepdim=True)  # (Q, 1)
    best = torch.full((q.shape[0],), float("inf"))
    for i in range(0, len(references), chunk):
        r = references[i : i + chunk].flatten(1)
        r = (r.float() / 255) if r.dtype == torch.uint8 else r.float()  # (R', D)
        dist = (q2 - 2 * q @ r.T + r.square().sum(1)[None]).clamp_min(0) / d  # (Q, R')
        best = torch.minimum(best, dist.min(1).values)
    return best


def generation_l2(model: Im2Vec, train: torch.Tensor, *, samples: int = 1000, seed: int = 0,
                  segments: int | None = None, prior: str = "auto") -> dict[str, float]:
    """Table 2, generation: ``samples`` latents from the prior (``infer.prior_latents``), decoded,
    each scored by the MSE to its nearest training image. ``train``: ``(N, 3, S, S)`` uint8 at
    the model size."""
    z = prior_latents(model, samples, seed=seed, prior=prior)
    e = nearest_mse(decoded_images(model, z, segments), train).tolist()
    return {**mean_stderr("generation_l2", e), "generated": len(e), "generation_prior": resolve_prior(model, prior)}


def held_out_l2(files: list[Path], train: torch.Tensor, size: int, fit: str) -> dict[str, float]:
    """Table 2's yardstick for ``generation_l2``: each test picture (``files``, brought to the model
    size as it fits pictures) scored the same way, by the MSE to its nearest training image. New
    real pictures lie this far from the training set; samples much nearer than them are close
    copies of training pictures more than new pictures of the kind."""
    x = torch.stack([fit_square(load_image(f), size, fit) for f in files])  # (N, 3, S, S) in [0, 1]
    return {**mean_stderr("held_out_l2", nearest_mse(x, train).tolist()), "held_out": len(files)}


def interpolation_l2(model: Im2Vec, train: torch.Tensor, *, pairs: int = 250, steps: int = 4, seed: int = 0,
                     segments: int | None = None) -> dict[str, float]:
    """Table 2, interpolation: ``pairs`` random training pairs, ``steps`` evenly spaced
    interpolants of their latents each (endpoints excluded), scored like ``generation_l2``."""
    g = torch.Generator().manual_seed(seed)
    idx = torch.randint(len(train), (pairs, 2), generator=g)
    imgs = [train[i].float() / 255 for i in idx.flatten().tolist()]
    z = encode(model, imgs).view(pairs, 2, -1)  # (pairs, 2, D)
    zs = torch.cat([lerp_latents(a, b, steps)[1:-1] for a, b in z])  # (pairs * steps, D)
    e = nearest_mse(decoded_images(model, zs, segments), train).tolist()
    return {**mean_stderr("interpolation_l2", e), "interpolants": len(e)}


def sweep_plot(series: dict[str, list[dict]], title: str = "") -> bytes:
    """PNG line plot of reconstruction L2 against k, one line per ``segments_sweep`` result
    (needs matplotlib: ``pip install 'im2vec[results]'``). No error bars: lines over the same
    images are paired, and their per-image spread says nothing about their difference."""
    try:
        from matplotlib.figure import Figure  # no pyplot: no global backend or figure state
    except ImportError:
        raise Im2VecError("the plot needs matplotlib: pip install 'im2vec[results]'") from None

    fig = Figure(figsize=(5.5, 3.6), dpi=120)
    ax = fig.subplots()
    for label, rows in series.items():
        k = [r["k"] for r in rows]
        ax.plot(k, [r["recon_l2"] for r in rows], marker="o", markersize=3, label=label)
    ax.set_xlabel("segments per path (k)")
    ax.set_ylabel("reconstruction L2")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()  # matplotlib writes the PNG itself (no Pillow image to hand to files.encode_png)
    fig.savefig(buf, format="png")
    return buf.getvalue()


# --- sample quality: improved precision and recall (Kynkäänniemi et al., NeurIPS 2019) -----------

PR_NEIGHBOURS = 3  # k of the k-NN balls (the paper's choice)
CONFIDENT = 0.9  # a sample the classifier labels with at least this probability counts as recognisable


def knn_radii(features: torch.Tensor, k: int = PR_NEIGHBOURS) -> torch.Tensor:
    """Distance from each of ``features (N, F)`` to its k-th nearest other point: ``(N,)``."""
    if len(features) <= k:
        raise ValueError(f"need more than k = {k} points, got {len(features)}")
    d = torch.cdist(features.double(), features.double())  # (N, N), 0 on the diagonal
    return d.kthvalue(k + 1, dim=1).values  # the 0 of the point itself is the first


def manifold_coverage(queries: torch.Tensor, support: torch.Tensor, k: int = PR_NEIGHBOURS) -> torch.Tensor:
    """Whether each of ``queries (Q, F)`` lies in some ball around ``support (N, F)`` of radius its
    k-th neighbour distance: ``(Q,)`` bool (the estimated manifold of the support set)."""
    radii = knn_radii(support, k)  # (N,)
    return (torch.cdist(queries.double(), support.double()) <= radii[None]).any(1)


def precision_recall(real: torch.Tensor, fake: torch.Tensor, k: int = PR_NEIGHBOURS) -> dict[str, float]:
    """Improved precision (share of ``fake (M, F)`` within the real manifold) and recall (share
    of ``real (N, F)`` within the fake manifold), features of one network."""
    if real.dim() != 2 or fake.dim() != 2 or real.shape[1] != fake.shape[1]:
        raise ValueError(f"features must be (N, F) and (M, F), got {tuple(real.shape)} and {tuple(fake.shape)}")
    return {"precision": float(manifold_coverage(fake, real, k).float().mean()),
            "recall": float(manifold_coverage(real, fake, k).float().mean())}


@torch.no_grad()
def features_of(net, images: torch.Tensor, batch: int = 512) -> tuple[torch.Tensor, torch.Tensor | None]:
    """Features ``(N, F)`` of ``images (N, 3, S, S)`` (uint8 or float in [0, 1]) and, for a
    classifier, the class probabilities ``(N, K)``."""
    feats, probs = [], []
    for i in range(0, len(images), batch):
        x = images[i : i + batch]
        x = x.float() / 255 if x.dtype == torch.uint8 else x.float()
        f = net(x)
        feats.append(f)
        if net.is_classifier:
            probs.append(torch.softmax(net.head(f), -1))
    return torch.cat(feats), (torch.cat(probs) if probs else None)


def confident_share(probs: torch.Tensor) -> float:
    """Share of images whose most likely class has probability >= ``CONFIDENT`` and is one of
    the data's (not a classifier's last, junk class): ``probs (N, K)``."""
    p, cls = probs.max(1)
    return float(((p >= CONFIDENT) & (cls < probs.shape[1] - 1)).float().mean())


def sample_quality(model, net, pictures: list[torch.Tensor], *, samples: int = 1000, seed: int = 0,
                   prior: str = "auto", temperature: float | None = None, segments: int | None = None) -> dict:
    """Precision and recall of ``samples`` decoded prior samples (rendered by cairosvg from the
    SVGs ``sample`` writes) against test ``pictures`` (``(3, H, W)`` each, of one size), in the
    feature space of ``net`` (``model.features.FeatureNet``); for a classifier also the share of
    samples it labels with probability >= ``CONFIDENT`` (and of the pictures). Both are brought
    into the net's frame: the pictures fitted its way, the samples (in the model's frame) first
    mapped back to the pictures' size when the model fits pictures another way (an MNIST model
    that resizes, a net that pads). With ``prior="auto"``, the same for
    the other priors the model has and N(0, I) under ``sample_quality_<prior>``, for comparison."""
    size, fit = net.config.image_size, net.config.fit
    if size != model.config.image_size:
        raise Im2VecError(f"the feature net takes {size} px images, the model draws {model.config.image_size} px")
    test = torch.stack([fit_square(p, size, fit) for p in pictures])  # (N, 3, S, S) in the net's frame
    h, w = pictures[0].shape[1:]
    real_f, real_p = features_of(net, (test * 255).round().to(torch.uint8))

    def scores(which: str) -> dict:
        z = prior_latents(model, samples, seed=seed, temperature=temperature, prior=which)
        fake = decoded_images(model, z, segments)  # (M, 3, S, S) in the model's frame
        if fit != model.config.fit:
            fake = torch.stack([fit_square(resize_square(x, max(h, w))[:, :h, :w], size, fit) for x in fake])
        fake_f, fake_p = features_of(net, fake)
        out = {**precision_recall(real_f, fake_f), "samples": samples, "test_images": len(test),
               "prior": resolve_prior(model, which), "temperature": sample_temperature(model, which, temperature)}
        if fake_p is not None:
            out["confident"] = confident_share(fake_p)
            out["confident_test"] = confident_share(real_p)
        return out

    out = scores(prior)
    if prior == "auto":  # the others the model has, for comparison
        for other in [p for p in STORED_PRIORS if stored_prior(model, p) is not None] + ["normal"]:
            if other != out["prior"]:
                out[f"sample_quality_{other}"] = scores(other)
    return out
