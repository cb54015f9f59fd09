"""refine/core.py: the one render + loss of refinement, its early stop, and pruning, against the
renderer and the pyramid L2 called directly."""

from __future__ import annotations

import numpy as np
import torch

from im2vec_cli.options import Plan
from im2vec_cli.raster import gaussian_pyramid, pyramid_l2, render_pyramid
from im2vec_cli.refine.core import _converged, _Fitter, _Progress
from im2vec_cli.vector import VectorImage, VectorShape, rasterize_svg
from tests.helpers import circle


def disc(cx: float, cy: float, r: float) -> np.ndarray:
    return circle(cx, cy, r).numpy()


def test_the_loss_is_the_pyramid_l2_of_the_render():
    target = torch.ones(2, 3, 24, 24, dtype=torch.float64)
    target[:, :, 6:18, 6:18] = 0.0
    s = Plan(levels=2)
    fit = _Fitter(target, 8, s)
    pts = torch.stack([circle(12, 12, r) / 24 for r in (5.0, 7.0)])[:, None]  # (2, 1, 24, 2) normalised
    colors, depth = torch.zeros(2, 1, 3, dtype=torch.float64), torch.zeros(2, 1, dtype=torch.float64)
    got = fit.loss(pts, colors, depth, torch.tensor([0, 1]), 0.5, fill_rule="nonzero", shape_index=None, counts=None)
    renders = render_pyramid(pts, colors, depth, size=(24, 24), levels=2, tau=0.5, fill_rule="nonzero", samples=8,
                             composite="over")
    torch.testing.assert_close(got, pyramid_l2(renders, gaussian_pyramid(target, 2), reduction="none"))
    assert got[1] < got[0]  # the larger disc is nearer the square


def test_an_image_stops_when_its_loss_has_not_improved_for_patience_steps():
    s = Plan(patience=3, min_improvement=0.01)
    assert not _converged([1.0, 0.9, 0.8], s)
    assert _converged([1.0, 0.5, 0.5, 0.499, 0.498], s)  # under 1% better than 0.5 in three steps
    assert not _converged([1.0, 0.5, 0.5, 0.499, 0.40], s)
    prog = _Progress(2, s)
    for loss in ([1.0, 1.0], [0.5, 0.9], [0.5, 0.8], [0.5, 0.7], [0.5, 0.6]):
        better, stopped = prog.record([loss[k] for k in prog.live])
    assert prog.live == [1] and prog.best == [0.5, 0.6] and stopped


def test_pruning_drops_a_path_that_changes_nothing_and_keeps_one_that_does():
    """A black disc drawn twice (the second hidden under the first) and a small disc elsewhere: the
    hidden copy goes, the disc the picture shows stays."""
    shown = VectorImage(32.0, 32.0, [VectorShape([disc(12, 12, 7), disc(25, 25, 3)], (0.0, 0.0, 0.0), "nonzero")])
    target = torch.from_numpy(rasterize_svg(shown.to_svg(), 32, 32)).permute(2, 0, 1)[None].to(torch.float64)
    drawn = VectorImage(32.0, 32.0, [VectorShape([disc(12, 12, 7), disc(25, 25, 3), disc(12, 12, 5)], (0.0, 0.0, 0.0),
                                                 "nonzero")])
    kept = _Fitter(target, 8, Plan()).prune(drawn, 0.01, 0)
    assert kept.num_paths == 2
    assert sorted(round(float(np.abs(c[:, 0] - c[:, 0].mean()).max())) for c in kept.shapes[0].contours) == [3, 7]
