"""The auxiliary loss against traced outlines (``outline``): its targets against the true
outlines of drawn pictures, the one-sided Chamfer distance against exact values and ``gradcheck``,
its long-range pull, and training phases that use it."""

import json
import math

import numpy as np
import pytest
import torch

from im2vec_cli.config import TrainConfig
from im2vec_cli.errors import ConfigError, Im2VecError
from im2vec_cli.events import DataLoaded, Tracing
from im2vec_cli.raster.bezier import flatten_closed
from im2vec_cli.training.outline import (
    MIN_PER_RING,
    OUTLINE_POINTS,
    outline_distances,
    outline_loss,
    outline_points,
    trace_targets,
)
from im2vec_cli.training.train import train
from im2vec_cli.vector import VectorImage, VectorShape, rasterize_svg, to_svg
from tests.helpers import circle, synthetic_shapes
from tests.test_train import MODEL, _stop_after, fast_cfg

S = 64


def _picture(contours, color=(0, 0, 0), background=None) -> np.ndarray:
    """``(S, S, 3)`` in [0, 1]: the contours (pixel frame) filled nonzero, rendered by cairosvg."""
    shapes = [VectorShape([c.numpy() for c in contours], color, "nonzero")]
    if background is not None:
        square = torch.tensor([[0, 0], [S, 0], [S, 0], [S, 0], [S, S], [S, S], [S, S], [0, S], [0, S], [0, S],
                               [0, 0], [0, 0]], dtype=torch.float64)
        shapes.insert(0, VectorShape([square.numpy()], background, "nonzero"))
    return rasterize_svg(to_svg(VectorImage(S, S, shapes)), S, S)


def test_the_outline_of_a_disc_lies_on_its_circle():
    """Every point is within a fifth of a pixel of the drawn circle, and they go all round it."""
    pts = outline_points(_picture([circle(30.0, 34.0, 17.0, segments=16)])) * S  # (M, 2) pixels
    assert pts.shape == (OUTLINE_POINTS, 2)
    r = np.hypot(pts[:, 0] - 30.0, pts[:, 1] - 34.0)
    assert np.abs(r - 17.0).max() < 0.2, np.abs(r - 17.0).max()
    angles = np.sort(np.arctan2(pts[:, 1] - 34.0, pts[:, 0] - 30.0))
    assert np.diff(np.concatenate([angles, angles[:1] + 2 * math.pi])).max() < 2 * 2 * math.pi / OUTLINE_POINTS


def test_a_hole_and_a_separate_piece_get_their_points():
    """A ring with a hole and a small dot apart from it: three rings, each with its share
    (at least ``MIN_PER_RING``), the dot's points on the dot."""
    ring = [circle(24.0, 32.0, 16.0, segments=16), circle(24.0, 32.0, 8.0, segments=16).flip(0)]
    dot = circle(54.0, 10.0, 3.0, segments=8)
    pts = outline_points(_picture(ring + [dot])) * S
    d_out = np.abs(np.hypot(pts[:, 0] - 24, pts[:, 1] - 32) - 16)
    d_in = np.abs(np.hypot(pts[:, 0] - 24, pts[:, 1] - 32) - 8)
    d_dot = np.abs(np.hypot(pts[:, 0] - 54, pts[:, 1] - 10) - 3)
    nearest = np.argmin(np.stack([d_out, d_in, d_dot]), axis=0)
    counts = np.bincount(nearest, minlength=3)
    assert counts.min() >= MIN_PER_RING and counts.sum() == OUTLINE_POINTS
    assert counts[0] > counts[1] > counts[2]  # by length
    assert np.min(np.stack([d_out, d_in, d_dot]), axis=0).max() < 0.3


def test_a_blank_picture_or_one_colour_has_no_outline_and_the_canvas_border_is_none():
    assert outline_points(np.ones((S, S, 3))) is None
    assert outline_points(np.zeros((S, S, 3))) is None  # all ink: only the canvas border
    pts = outline_points(_picture([circle(32.0, 32.0, 12.0, segments=16)], color=(1, 1, 1), background=(0, 0, 1)))
    assert pts is not None and np.abs(np.hypot(*(pts * S - 32).T) - 12).max() < 0.3  # the disc, not the border


def test_trace_targets_marks_blank_pictures_and_reports_progress():
    shapes = synthetic_shapes(3, 32)
    x = torch.cat([shapes, torch.full((1, 3, 32, 32), 255, dtype=torch.uint8)])
    seen = []
    o = trace_targets(x, lambda done, n: seen.append((done, n)))
    assert o.points.shape == (4, OUTLINE_POINTS, 2) and o.valid.tolist() == [True, True, True, False]
    assert seen == [(4, 4)]


def test_chamfer_is_zero_on_its_own_points_and_the_square_of_a_small_shift():
    """Targets sampled on the path as the loss samples it: 0; the path shifted by 0.1 px (well
    under half the spacing of its points): each nearest point is its shifted self, 0.01 px^2."""
    path = circle(0.5, 0.5, 0.3, segments=8).float()[None, None]  # (1, 1, 24, 2) model frame
    target = flatten_closed(path, 4).flatten(1, 2)  # (1, 32, 2)
    valid = torch.ones(1, dtype=torch.bool)
    assert outline_loss(path, target, valid, S).item() < 1e-6
    shifted = path + torch.tensor([0.1 / S, 0.0])
    assert outline_loss(shifted, target, valid, S).item() == pytest.approx(0.01, rel=1e-3)


def test_a_path_inside_the_ink_costs_nothing_a_missed_part_costs_its_distance():
    """One-sided: a second path whose boundary runs inside the picture (overlapping the first,
    as parts of a crack-free union do) adds nothing; the outline of a part no path reaches
    costs its squared distance to the nearest path point."""
    outer = circle(0.5, 0.5, 0.3, segments=8).float()  # (24, 2)
    target = flatten_closed(outer[None, None], 4).flatten(1, 2)  # (1, 32, 2) on the outer path
    inner = circle(0.45, 0.5, 0.1, segments=8).float()
    valid = torch.ones(1, dtype=torch.bool)
    assert outline_loss(torch.stack([outer, inner])[None], target, valid, S).item() < 1e-6
    dot = target[:, :1] + torch.tensor([0.1, 0.0])  # one more outline point 0.1 beyond the path at (0.8, 0.5)
    with_dot = torch.cat([target, dot], dim=1)  # (1, 33, 2)
    assert outline_loss(outer[None, None], with_dot, valid, S).item() == pytest.approx((0.1 * S) ** 2 / 33, rel=1e-3)
    d2 = outline_distances(outer[None, None], with_dot, S)  # (1, 33): per point, what bench/research/outline_reach reads
    assert d2.shape == (1, 33) and d2[0, :32].max().item() < 1e-6
    assert d2[0, 32].item() == pytest.approx((0.1 * S) ** 2, rel=1e-3)


def test_pictures_without_an_outline_count_for_nothing():
    path = circle(0.5, 0.5, 0.3).float()[None, None].repeat(2, 1, 1, 1)  # (2, 1, 24, 2)
    near = flatten_closed(path[:1], 4).flatten(1, 2)
    far = near + 0.4
    both = outline_loss(path, torch.cat([near, far]), torch.tensor([True, False]), S)
    assert both.item() == pytest.approx(outline_loss(path[:1], near, torch.tensor([True]), S).item(), abs=1e-6)
    assert outline_loss(path, torch.cat([near, far]), torch.tensor([False, False]), S).item() == 0.0


def test_gradcheck():
    g = torch.Generator().manual_seed(0)
    path = (0.5 + 0.3 * torch.rand(1, 2, 12, 2, generator=g, dtype=torch.float64)).requires_grad_()
    target = torch.rand(1, 20, 2, generator=g, dtype=torch.float64)
    assert torch.autograd.gradcheck(lambda p: outline_loss(p, target, torch.tensor([True]), S), (path,))


def test_the_pull_reaches_a_part_far_from_every_path():
    """A path drawn 30 px from the only disc in the picture: the renderer's gradient is nil
    there, the outline loss alone brings the path to every stretch of the disc's outline."""
    target = torch.from_numpy(outline_points(_picture([circle(46.0, 44.0, 9.0, segments=16)]))).float()[None]
    path = circle(20 / S, 20 / S, 6 / S, segments=8).float()[None, None].requires_grad_()
    opt = torch.optim.Adam([path], lr=0.01)
    start = outline_loss(path, target, torch.tensor([True]), S).item()
    for _ in range(300):
        opt.zero_grad()
        loss = outline_loss(path, target, torch.tensor([True]), S)
        loss.backward()
        opt.step()
    assert start > 300 and loss.item() < 4, (start, loss.item())  # from 30 px away to within 2 px (rms)
    reach = torch.cdist(target[0] * S, flatten_closed(path.detach(), 4)[0, 0] * S).min(dim=1).values  # (M,)
    assert reach.max() < 4, reach.max()  # every stretch of the disc's outline has the path near it


@pytest.fixture(scope="module")
def shapes():
    return synthetic_shapes(64, 32)


def test_an_outline_phase_logs_its_term_and_resumes_exactly(tmp_path, shapes):
    """The targets are traced at the start (and again on resume, the same), every step logs
    the term, and a run stopped and resumed ends with the weights of the straight run."""
    cfg = fast_cfg(steps=6, ckpt_every=3, outline=0.01)
    events = []
    train(None, tmp_path / "a", MODEL, cfg, images=shapes, on_event=events.append)
    traced = [e for e in events if isinstance(e, Tracing)]
    loaded = [e for e in events if isinstance(e, DataLoaded)][0]
    assert traced and traced[-1].done == traced[-1].images == loaded.train  # every training image
    logged = [json.loads(s) for s in (tmp_path / "a" / "metrics.jsonl").read_text().splitlines()]
    steps = [e for e in logged if e["event"] == "train"]
    assert len(steps) == 6 and all(e["outline"] > 0 for e in steps)
    assert all(e["loss"] > e["pyramid_l2"] + 0.01 * e["outline"] - 1e-6 for e in steps)
    with pytest.raises(KeyboardInterrupt):
        train(None, tmp_path / "b", MODEL, fast_cfg(steps=6, ckpt_every=100, outline=0.01), images=shapes,
              on_event=_stop_after(3))
    train(None, tmp_path / "b", MODEL, cfg, images=shapes, resume=True)
    a = torch.load(tmp_path / "a" / "checkpoint.pt", weights_only=True)
    b = torch.load(tmp_path / "b" / "checkpoint.pt", weights_only=True)
    assert a["step"] == b["step"] == 6
    for k in a["model"]:
        assert torch.allclose(a["model"][k], b["model"][k], atol=1e-6), k


def test_bad_outline_settings_are_refused(tmp_path, shapes):
    with pytest.raises(ConfigError):
        TrainConfig(outline=-1.0)
    with pytest.raises(ConfigError):
        TrainConfig(outline=float("nan"))
    import dataclasses

    with pytest.raises(Im2VecError, match="outline > 0 .* imagevae has none"):
        train(None, tmp_path / "run", dataclasses.replace(MODEL, arch="imagevae"), fast_cfg(steps=2, outline=1.0),
              images=shapes)
    assert not (tmp_path / "run").exists()
