"""The Im2Vec VAE: encoder -> z -> path codes -> closed cubic paths -> soft raster."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import torch
from torch import nn

from ..config import ModelConfig
from ..options import GROUPINGS
from ..raster import render_coverage, render_supersampled, solve_colors, solve_order
from ..raster.bezier import flatten_closed, polygon_area
from .decoder import PathCodes, PathDecoder
from .encoder import Encoder, Feedback, PathPass, sample_latent
from .points import PointPass
from .segments import SegmentPredictor, choose_segments

FEEDBACK_TAU = 0.4  # edge softness (px) of the renders a feedback pass sees: trained models depend on it
COLOR_TAU, COLOR_RIDGE = 0.2, 1e-3  # ModelConfig.solve_colors: coverage softness (px), pull to the network's colour
# (64 emoji test assets, phase 18: 0.01950 -> 0.0178 for tau 0.15-0.3 and ridge 1e-4-1e-3; 0.6 px or 1e-2 worse)


def parse_palette(spec: str) -> torch.Tensor | None:
    """``"#rrggbb,#rrggbb"`` -> ``(K, 3)`` in [0, 1], or ``None`` for an empty spec."""
    if not spec:
        return None
    cols = []
    for c in spec.split(","):
        c = c.strip().lstrip("#")
        if len(c) != 6:
            raise ValueError(f"palette colours must be #rrggbb, got {c!r}")
        cols.append([int(c[i : i + 2], 16) / 255 for i in (0, 2, 4)])
    return torch.tensor(cols)


@dataclass
class Decoded:
    """Decoder output for a batch.

    points ``(B, P, 3k, 2)`` normalised frame; colors ``(B, G, 3)``; depth ``(B, G)``;
    shape_index ``(P,)`` or ``None`` (G = P); fill_rule of every shape; counts ``(B, P)``
    segments of each path when they differ (``segments="auto"``), else ``None``. A path with
    fewer than k segments is padded with zero-length segments at its first anchor, which
    render exactly like the unpadded path.
    """

    points: torch.Tensor
    colors: torch.Tensor
    depth: torch.Tensor
    shape_index: torch.Tensor | None
    fill_rule: str
    counts: torch.Tensor | None = None


class Im2Vec(nn.Module):
    """The model of the paper (sec. 3), configured by ``ModelConfig``."""

    raster_output = False

    def __init__(self, config: ModelConfig):
        super().__init__()
        if config.arch != "im2vec":
            raise ValueError(f"Im2Vec needs arch 'im2vec', got {config.arch!r} (use model.imagevae.build_model)")
        if config.grouping not in GROUPINGS:
            raise ValueError(f"grouping must be one of {GROUPINGS}, got {config.grouping!r}")
        self.config = config
        self.encoder = Encoder(config.image_size, config.channels, config.latent, config.enc_width)
        self.feedback = (Feedback(config.image_size, config.channels, config.latent, config.enc_width,
                                  config.paths if config.feedback_paths else 0) if config.feedback else None)
        self.path_pass = (PathPass(config.image_size, config.channels, config.code, config.path_pass_width)
                          if config.path_passes else None)
        self.point_pass = (PointPass(config.channels, config.point_pass_width, smooth=config.point_smooth)
                           if config.point_passes else None)
        self.codes = PathCodes(config.latent, config.lstm_hidden, config.code, config.paths)
        self.decoder = PathDecoder(config.code, config.dec_width, config.dec_layers, config.deform, config.deform_width)
        # Distinct start positions: identical initial circles would cancel under even-odd.
        ang = torch.arange(config.paths) * (2 * math.pi / config.paths)
        spread = 0.2 if config.paths > 1 else 0.0
        centres = 0.5 + spread * torch.stack([ang.cos(), ang.sin()], -1)  # (P, 2)
        self.register_buffer("centres", centres, persistent=False)
        pal = parse_palette(config.palette)
        self.register_buffer("palette", pal if pal is not None else torch.zeros(0, 3), persistent=False)
        if pal is not None:
            self.palette_logits = nn.Linear(2 * config.lstm_hidden, pal.shape[0])
        self.segment_predictor = (SegmentPredictor(config.code, config.segment_predictor)
                                  if config.segment_predictor else None)

    def encode(self, images: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(B, C, S, S)`` in [0, 1] -> ``mu, logvar (B, D)``: the encoder's guess, corrected by
        ``config.feedback`` render-and-compare passes (``Feedback``; the render, and with
        ``config.feedback_paths`` each path's coverage, are inputs, not differentiated through).

        With ``config.feedback_select``, outside training, ``mu`` is per picture the guess (the
        encoder's or a pass's) whose render is closest to it in mean squared error: a module
        trained for some passes helps most pictures with more and drifts on a few, and the render
        each pass draws anyway tells which. It costs one render more (of the last guess)."""
        cfg = self.config
        mu, logvar = self.encoder(images)
        select = cfg.feedback_select and not self.training
        best, best_err = mu, mu.new_full((len(mu),), math.inf)
        for i in range(cfg.feedback + select):
            with torch.no_grad():
                seen, parts = self._look(self.decode(mu), images, cfg.feedback_paths and i < cfg.feedback)
            if select:
                better, best_err = _closer(seen, images, best_err)
                best = torch.where(better[:, None], mu, best)
            if i < cfg.feedback:
                mu = self.feedback(images, seen, mu, parts)
        return (best if select else mu), logvar

    def decode(self, z: torch.Tensor, segments: int | torch.Tensor | None = None,
               images: torch.Tensor | None = None, solve: bool = False) -> Decoded:
        """``z (B, D)`` -> closed cubic paths.

        ``segments``: k for every path (default ``config.segments``), or a ``(B, P)`` tensor of
        per-path counts (e.g. from ``choose_segments``), padded as described in ``Decoded``.
        ``images (B, C, S, S)``: the pictures ``z`` encodes, for the model's path passes
        (``config.path_passes``, ``_path_passes``) and point passes (``config.point_passes``,
        ``draw``); without them, the paths of ``z`` alone.
        ``solve``: colours solved in training too (``path_state``).
        """
        return self.draw(*self.path_state(z, images, solve), segments, images)

    def draw(self, code: torch.Tensor, depth: torch.Tensor, color: torch.Tensor,
             segments: int | torch.Tensor | None = None, images: torch.Tensor | None = None) -> Decoded:
        """Each path's code ``(B, P, C)``, depth ``(B, P)`` and colour ``(B, P, 3)`` (``path_state``)
        -> closed cubic paths, grouped as ``config.grouping`` says; ``segments`` as ``decode`` takes it.
        With ``images (B, C, S, S)``, the pictures they were drawn for, the paths' outlines are then
        moved by the model's point passes (``config.point_passes``, ``_point_passes``)."""
        cfg = self.config
        b = code.shape[0]
        counts = None
        if isinstance(segments, torch.Tensor):
            counts = segments.to(code.device).long()
            if counts.shape != (b, cfg.paths) or counts.min() < 1:
                raise ValueError(f"per-path segments must be (B, P) = ({b}, {cfg.paths}) counts >= 1")
            centre = self.centres.to(code.dtype).expand(b, -1, -1).flatten(0, 1)  # (B*P, 2)
            pts = self._decode_ragged(code.flatten(0, 1), counts.flatten(), centre).view(b, cfg.paths, -1, 2)
        else:
            k = segments or cfg.segments
            if k < 1:
                raise ValueError(f"segments must be >= 1, got {k}")
            pts = self.path_points(code, k)  # (B, P, 3k, 2)
        if cfg.grouping in ("evenodd", "nonzero"):
            # one shape, all paths under that fill rule: its colour is the mean of the path colours
            dec = Decoded(pts, color.mean(1, keepdim=True), depth.new_zeros(b, 1),
                          torch.zeros(cfg.paths, dtype=torch.long, device=code.device), cfg.grouping, counts)
        else:
            dec = Decoded(pts, color, depth, None, "nonzero", counts)
        return self._point_passes(images, dec) if images is not None and self.point_pass is not None else dec

    def _point_passes(self, images: torch.Tensor, dec: Decoded) -> Decoded:
        """``config.point_passes`` passes of ``PointPass`` on the outlines of ``dec``, drawn for
        ``images (B, C, S, S)``, each seeing the render of the last (``_look``); a path of fewer
        segments than ``dec``'s widest is moved alone and padded again (``Decoded``). With
        ``config.feedback_select``, outside training, per picture the pass (or the start) whose
        render is closest to it, as ``encode`` chooses; with ``config.solve_colors``, outside training,
        the colours then solved again for the outlines as moved (``path_state``)."""
        cfg = self.config
        select = cfg.feedback_select and not self.training
        b, p, m, _ = dec.points.shape
        rows = torch.arange(b, device=images.device).repeat_interleave(p)  # (B*P,) picture of each path
        counts = (dec.counts.flatten() if dec.counts is not None
                  else torch.full((b * p,), m // 3, dtype=torch.long, device=images.device))
        best, best_err = dec.points, images.new_full((b,), math.inf)
        for i in range(cfg.point_passes + select):
            with torch.no_grad():
                seen = self._look(dec, images, False)[0]
            if select:
                better, best_err = _closer(seen, images, best_err)
                best = torch.where(better[:, None, None, None], dec.points, best)
            if i == cfg.point_passes:
                break
            flat = dec.points.flatten(0, 1)  # (B*P, 3K, 2)
            moved = flat.clone()
            for k in counts.unique().tolist():
                sel = counts == k
                out = self.point_pass(images, seen, flat[sel, : 3 * k], rows[sel])  # (n, 3k, 2)
                moved[sel] = torch.cat([out, out[:, :1].expand(-1, m - 3 * k, -1)], 1)
            dec = dataclasses.replace(dec, points=moved.view(b, p, m, 2))
        dec = dataclasses.replace(dec, points=best) if select else dec
        if cfg.solve_colors and not self.training:  # the colours solved again for the outlines as moved
            cover, target = self._color_problem(dec.points, images)
            dec = dataclasses.replace(dec, colors=solve_colors(cover, dec.depth, target, dec.colors, COLOR_RIDGE))
        return dec

    def _color_problem(self, points: torch.Tensor, images: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """What the colour and order solves take of paths ``(B, P, 3k, 2)`` drawn for ``images (B, C, S, S)``:
        each path's coverage ``(B, P, S, S)`` at ``COLOR_TAU`` and the pictures as ``(B, 3, S, S)``."""
        cfg = self.config
        cover = render_coverage(points, size=cfg.image_size, tau=COLOR_TAU, samples=cfg.samples).to(images.dtype)
        return cover, images.expand(-1, 3, -1, -1)

    def path_state(self, z: torch.Tensor, images: torch.Tensor | None = None, solve: bool = False,
                   colors: bool = True) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``z (B, D)`` -> each path's code ``(B, P, C)``, depth ``(B, P)`` and colour ``(B, P, 3)``,
        corrected by the path passes when ``images`` are given (``decode``); with
        ``config.solve_colors``, outside training or with ``solve`` (``TrainConfig.solved``: the
        loss differentiates through the solve), the colours then those whose render is closest to
        the pictures (``raster.solve_colors``, the shapes as drawn); with ``config.solve_order``,
        outside training, the layers' order first (``raster.solve_order``). ``colors=False`` skips
        both solves, for callers that use the codes alone."""
        code, depth, color, h = self.codes(z)  # (B, P, C), (B, P), (B, P, 3), (B, P, 2H)
        if self.palette.numel():
            # fixed palette (colour-segmented data): a soft choice among its colours
            color = torch.softmax(self.palette_logits(h), -1) @ self.palette.to(h.dtype)  # (B, P, 3)
        if images is not None and self.path_pass is not None:
            code, color = self._path_passes(images, code, depth, color)
        if images is not None and colors and self.config.solve_colors and (solve or not self.training):
            cover, target = self._color_problem(self.path_points(code, self.config.segments), images)
            if self.config.solve_order and not self.training:
                depth = solve_order(cover, depth, target, color, COLOR_RIDGE)
            color = solve_colors(cover, depth, target, color, COLOR_RIDGE)
        return code, depth, color

    def _path_passes(self, images: torch.Tensor, code: torch.Tensor, depth: torch.Tensor,
                     color: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``config.path_passes`` passes of ``PathPass`` on the codes ``(B, P, C)`` and colours
        ``(B, P, 3)`` of pictures ``images``, each seeing the render (at ``config.segments``, the
        feedback passes' softness) of the last; a fixed palette keeps its colours. With
        ``config.feedback_select``, outside training, per picture the pass (or the start) whose
        render is closest to it, as ``encode`` chooses."""
        cfg = self.config
        select = cfg.feedback_select and not self.training
        best, best_err = (code, color), code.new_full((len(code),), math.inf)
        for i in range(cfg.path_passes + select):
            with torch.no_grad():
                seen, parts = self._look(self.draw(code, depth, color), images, i < cfg.path_passes)
            if select:
                better, best_err = _closer(seen, images, best_err)
                best = (torch.where(better[:, None, None], code, best[0]),
                        torch.where(better[:, None, None], color, best[1]))
            if i < cfg.path_passes:
                new_code, new_color = self.path_pass(images, seen, parts, code, color)
                code, color = new_code, (color if self.palette.numel() else new_color)
        return best if select else (code, color)

    def _look(self, dec: Decoded, images: torch.Tensor, coverage: bool) -> tuple[torch.Tensor, torch.Tensor | None]:
        """What a pass sees of ``dec`` beside ``images (B, C, S, S)``: its render ``(B, C, S, S)`` at
        ``FEEDBACK_TAU`` and, with ``coverage``, each path's own ``(B, P, S, S)`` at the same softness."""
        cfg = self.config
        seen = self.render(dec, tau=FEEDBACK_TAU).to(images.dtype)  # (B, 3, S, S)
        parts = (render_coverage(dec.points, size=cfg.image_size, tau=FEEDBACK_TAU, samples=cfg.samples)
                 .to(images.dtype) if coverage else None)
        return (seen.mean(1, keepdim=True) if images.shape[1] == 1 else seen), parts

    def path_points(self, code: torch.Tensor, k: int) -> torch.Tensor:
        """Per-path codes ``(B, P, C)`` -> closed paths of ``k`` segments ``(B, P, 3k, 2)`` by the
        path decoder alone (``decode`` without the LSTM: projection fits the codes directly)."""
        b, p = code.shape[:2]
        centre = self.centres.to(code.dtype).expand(b, -1, -1).flatten(0, 1)  # (B*P, 2)
        return self.decoder(code.flatten(0, 1), k, centre).view(b, p, 3 * k, 2)

    def _decode_ragged(self, code: torch.Tensor, counts: torch.Tensor, centre: torch.Tensor) -> torch.Tensor:
        """``code (N, C)``, ``counts (N,)`` -> ``(N, 3K, 2)``, K = max count, padded at anchor 0."""
        big = int(counts.max())
        out = code.new_empty(len(code), 3 * big, 2)
        for k in counts.unique().tolist():
            sel = counts == k
            pts = self.decoder(code[sel], k, centre[sel])  # (n, 3k, 2)
            pad = pts[:, :1].expand(-1, 3 * (big - k), -1)
            out[sel] = torch.cat([pts, pad], 1)
        return out

    def choose_segments(self, z: torch.Tensor, quality: float, images: torch.Tensor | None = None) -> torch.Tensor:
        """Per-path segment counts ``(B, P)`` for quality threshold ``quality`` (sec. 3.3), of the
        paths ``decode(z, ..., images)`` draws (with ``images``, the path passes' codes)."""
        return self.code_segments(self.path_state(z, images, colors=False)[0], quality)

    def code_segments(self, code: torch.Tensor, quality: float) -> torch.Tensor:
        """``choose_segments`` of the paths of codes ``(B, P, C)`` (``draw``)."""
        if self.segment_predictor is None:
            raise ValueError("this model has no segment predictor (train one with `im2vec train-aux`)")
        params = self.segment_predictor(code.flatten(0, 1))
        return choose_segments(params, quality, self.config.max_segments).view(code.shape[:2])

    def render(self, dec: Decoded, size: int | None = None, tau: float = 0.4, composite: str = "soft",
               supersample: int = 1) -> torch.Tensor:
        """Rasterise decoded paths to ``(B, 3, size, size)``; ``supersample > 1``: box-filtered
        from a render at that many times the size (``render_supersampled``)."""
        cfg = self.config
        return render_supersampled(
            dec.points, dec.colors, dec.depth, size=size or cfg.image_size, factor=supersample, tau=tau,
            fill_rule=dec.fill_rule, shape_index=dec.shape_index, samples=cfg.samples, composite=composite,
        )

    def forward(self, images: torch.Tensor, segments: int | None = None, sample: bool = True, solve: bool = False):
        """Reconstruct a batch. Returns ``(Decoded, mu, logvar)``; ``z = mu`` when not sampling;
        ``solve`` as ``decode`` takes it."""
        mu, logvar = self.encode(images)
        return self.decode(sample_latent(mu, logvar, sample), segments, images, solve), mu, logvar

    @staticmethod
    def path_areas(points: torch.Tensor, samples: int = 8) -> torch.Tensor:
        """Absolute area of each path in normalised units, ``(B, P, 3k, 2) -> (B, P)``;
        unused paths collapse to ~0 and are dropped on export."""
        return polygon_area(flatten_closed(points, samples)).abs()


def _closer(seen: torch.Tensor, images: torch.Tensor, best_err: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Per picture, whether the render ``seen`` is closer to ``images`` (mean squared error) than
    ``best_err (B,)``, and the lower of the two errors."""
    err = (seen - images).pow(2).flatten(1).mean(1)  # (B,)
    return err < best_err, torch.minimum(err, best_err)
