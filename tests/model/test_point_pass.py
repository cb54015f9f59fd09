"""The point pass (``ModelConfig.point_passes``, ``model.points.PointPass``): each path's outline
moved across and along itself from profiles read on it, checked against the cubic evaluated
by hand, ``gradcheck``, and a pass trained to follow an edge it is shown."""

import math

import pytest
import torch

from im2vec_cli.config import MAX_FEEDBACK, ModelConfig, TrainConfig
from im2vec_cli.errors import Im2VecError, ModelError
from im2vec_cli.model.points import MAX_MOVE, PointPass, curve_samples, from_samples
from im2vec_cli.model.pretrained import from_pretrained, grow_state, save_pretrained
from im2vec_cli.model.vae import COLOR_RIDGE, COLOR_TAU, Im2Vec
from im2vec_cli.raster import render_coverage, solve_colors
from im2vec_cli.training.distill import freeze
from tests.helpers import descend

TINY = dict(image_size=32, latent=16, enc_width=8, lstm_hidden=16, code=8, dec_width=16, dec_layers=3, deform_width=8,
            point_pass_width=16)


def _cubic(p0, c1, c2, p3, t):
    """The cubic Bezier at ``t``, by de Casteljau's construction (independent of the Bernstein form)."""
    lerp = lambda a, b: a + t * (b - a)  # noqa: E731
    a, b, c = lerp(p0, c1), lerp(c1, c2), lerp(c2, p3)
    d, e = lerp(a, b), lerp(b, c)
    return lerp(d, e)


def _circles(n: int, k: int, radius: float) -> torch.Tensor:
    """Closed cubic circles ``(n, 3k, 2)`` about the canvas centre (the usual 4/3 tan handles)."""
    t = torch.arange(k, dtype=torch.float64) * (2 * math.pi / k)
    h = 4 / 3 * math.tan(math.pi / (2 * k))
    on = torch.stack([t.cos(), t.sin()], -1)
    tan = torch.stack([-t.sin(), t.cos()], -1)
    nxt = on.roll(-1, 0)
    ntan = tan.roll(-1, 0)
    pts = torch.stack([on, on + h * tan, nxt - h * ntan], 1).flatten(0, 1)  # (3k, 2)
    return (0.5 + radius * pts).expand(n, -1, -1).clone()


def test_curve_samples_are_the_cubic_at_thirds_and_invert_exactly():
    torch.manual_seed(0)
    pts = torch.rand(5, 3 * 7, 2, dtype=torch.float64)
    q = curve_samples(pts)
    p0, c1, c2 = pts[:, 0::3], pts[:, 1::3], pts[:, 2::3]
    p3 = p0.roll(-1, 1)
    for j, t in enumerate((0.0, 1 / 3, 2 / 3)):
        assert torch.allclose(q[:, j::3], _cubic(p0, c1, c2, p3, t), atol=1e-12)
    assert torch.allclose(from_samples(q), pts, atol=1e-12)


def test_a_fresh_pass_moves_nothing_and_a_trained_one_moves_at_most_its_bound():
    torch.manual_seed(1)
    pp = PointPass(3, width=16).double()
    x, seen = torch.rand(2, 3, 32, 32, dtype=torch.float64), torch.rand(2, 3, 32, 32, dtype=torch.float64)
    pts = _circles(4, 6, 0.3)
    rows = torch.tensor([0, 0, 1, 1])
    assert torch.equal(pp(x, seen, pts, rows), pts)
    torch.nn.init.normal_(pp.net[-1].weight, std=10.0)
    moved = curve_samples(pp(x, seen, pts, rows)) - curve_samples(pts)  # (N, 3k, 2)
    assert moved.abs().max() > 0.1 / 32
    assert moved.norm(dim=-1).max() <= math.sqrt(2) * MAX_MOVE / 32 + 1e-9


def test_the_pass_is_differentiable_gradcheck():
    torch.manual_seed(2)
    pp = PointPass(1, width=8, layers=2).double()
    torch.nn.init.normal_(pp.net[-1].weight, std=0.5)
    x = torch.rand(1, 1, 16, 16, dtype=torch.float64)
    seen = torch.rand(1, 1, 16, 16, dtype=torch.float64)
    pts = (_circles(1, 3, 0.2) + 0.013).requires_grad_(True)  # points off the pixel grid's kinks
    w = pp.net[0].weight
    assert torch.autograd.gradcheck(lambda p, w_: torch.func.functional_call(pp, {"net.0.weight": w_},
                                                                             (x, seen, p, torch.tensor([0]))),
                                    (pts, w.detach().clone().requires_grad_(True)), atol=1e-6)


def test_a_pass_learns_to_follow_the_edge_it_is_shown():
    """A disc drawn 2.5 px larger than the circle the paths start on: a pass trained through the
    renderer (the paths fixed, the picture given) moves the outline out to it, for discs of
    other sizes than the one it learned on too."""
    torch.manual_seed(3)
    s, k = 32, 6
    pp = PointPass(1, width=16, layers=3).double()

    def case(r: float):
        pts = _circles(1, k, r / s)
        yy, xx = torch.meshgrid(torch.arange(s) + 0.5, torch.arange(s) + 0.5, indexing="ij")
        disc = ((xx - s / 2) ** 2 + (yy - s / 2) ** 2).sqrt().double() < r + 2.5
        x = (1.0 - disc.double())[None, None]  # black disc on white
        seen = 1 - render_coverage(pts[None], size=s, tau=0.4, samples=4).sum(1, keepdim=True).clamp(max=1)
        return x, seen, pts

    def error(r: float) -> torch.Tensor:
        x, seen, pts = case(r)
        cover = render_coverage(pp(x, seen, pts, torch.tensor([0]))[None], size=s, tau=0.4, samples=4)
        return (1 - cover.sum(1, keepdim=True).clamp(max=1) - x).square().mean()

    with torch.no_grad():
        other = float(error(7.0))
    before, after = descend(lambda: error(9.0), list(pp.parameters()))
    assert after < 0.5 * before
    with torch.no_grad():
        assert float(error(7.0)) < 0.7 * other


def _bars() -> torch.Tensor:
    x = torch.ones(4, 3, 32, 32)
    for i, r in enumerate((4, 6, 8, 10)):
        x[i, :, 16 - r : 16 + r, 10 : 10 + r] = 0.0
    return x


def test_grown_in_it_draws_as_before_then_pads_stay_pads_and_selection_keeps_the_closest(tmp_path):
    torch.manual_seed(4)
    old, new = ModelConfig(paths=3, feedback=1, **TINY), ModelConfig(paths=3, feedback=1, point_passes=2, **TINY)
    base = Im2Vec(old).eval()
    torch.nn.init.normal_(base.decoder.net[-1].weight, std=0.05)
    model = Im2Vec(new).eval()
    model.load_state_dict(grow_state(base.state_dict(), old, new, seed=2))  # strict
    x = _bars()
    with torch.no_grad():
        mu = model.encode(x)[0]
        assert torch.equal(base.decode(mu, 8, x).points, model.decode(mu, 8, x).points)
        torch.nn.init.normal_(model.point_pass.net[-1].weight, std=0.5)  # a pass that moves, some the wrong way
        moved = model.decode(mu, 8, x).points
        assert not torch.allclose(moved, base.decode(mu, 8, x).points)
        assert torch.equal(model.decode(mu, 8).points, base.decode(mu, 8).points)  # no pictures: no pass
        counts = torch.tensor([[5, 8, 3]]).expand(4, -1)
        ragged = model.decode(mu, counts, x).points  # (B, P, 24, 2)
        for p, k in enumerate((5, 8, 3)):
            pad = ragged[:, p, 3 * k :]
            assert torch.equal(pad, ragged[:, p, :1].expand_as(pad))  # zero-length segments at anchor 0
        picked = Im2Vec(ModelConfig(paths=3, feedback=1, feedback_select=True, point_passes=2, **TINY)).eval()
        picked.load_state_dict(model.state_dict())
        chain = [base.decode(mu, 8, x)]
        for _ in range(2):
            seen = model._look(chain[-1], x, False)[0]
            rows = torch.arange(4).repeat_interleave(3)
            pts = model.point_pass(x, seen, chain[-1].points.flatten(0, 1), rows).view(4, 3, 24, 2)
            chain.append(type(chain[-1])(**{**chain[-1].__dict__, "points": pts}))
        err = torch.stack([(model._look(d, x, False)[0] - x).square().flatten(1).mean(1) for d in chain], 1)
        want = torch.stack([d.points for d in chain], 1)[torch.arange(4), err.argmin(1)]
        assert torch.allclose(picked.decode(mu, 8, x).points, want, atol=1e-6)
        assert torch.allclose(moved, chain[-1].points, atol=1e-6)
    freeze(model, TrainConfig(train_only="point_pass").train_only)
    learning = [n for n, p in model.named_parameters() if p.requires_grad]
    assert learning and all(n.startswith("point_pass.") for n in learning)
    save_pretrained(model, tmp_path / "m")
    with torch.no_grad():
        assert torch.allclose(from_pretrained(tmp_path / "m").decode(mu, 8, x).points, moved, atol=1e-3)  # fp16
    with pytest.raises(Im2VecError, match="point_passes"):
        ModelConfig(point_passes=MAX_FEEDBACK + 1, **TINY)
    with pytest.raises(ModelError, match="point_pass_width"):
        grow_state(model.state_dict(), new, ModelConfig(**{**TINY, "paths": 3, "feedback": 1, "point_passes": 2,
                                                          "point_pass_width": 32}))
    Im2Vec(old).load_state_dict(grow_state(model.state_dict(), new, old))  # strict: the pass dropped


def test_solved_colours_are_solved_again_for_the_moved_outlines():
    torch.manual_seed(5)
    cfg = ModelConfig(grouping="layers", paths=3, solve_colors=True, point_passes=1, **TINY)
    model = Im2Vec(cfg).eval()
    torch.nn.init.normal_(model.decoder.net[-1].weight, std=0.05)
    torch.nn.init.normal_(model.point_pass.net[-1].weight, std=0.5)
    x = 1 - (1 - _bars()) * torch.tensor([0.1, 0.7, 0.9]).view(1, 3, 1, 1)
    with torch.no_grad():
        mu = model.encode(x)[0]
        code, depth, first = model.path_state(mu, x)  # solved for the outlines before the pass
        dec = model.decode(mu, None, x)
        cover = render_coverage(dec.points, size=32, tau=COLOR_TAU, samples=cfg.samples)
        assert torch.allclose(dec.colors, solve_colors(cover, depth, x, first, COLOR_RIDGE), atol=1e-5)
        assert not torch.allclose(dec.colors, first, atol=1e-4)


def test_smoothing_low_passes_the_moves_along_the_outline():
    """``smooth = 2``: the moves of the same weights through a [1, 4, 6, 4, 1] / 16 circular
    filter, so a wiggle two samples long is cut to a quarter and the mean move is kept."""
    torch.manual_seed(6)
    free, smooth = PointPass(3, width=16).double(), PointPass(3, width=16, smooth=2).double()
    torch.nn.init.normal_(free.net[-1].weight, std=0.3)
    smooth.load_state_dict(free.state_dict())
    x, seen = torch.rand(1, 3, 32, 32, dtype=torch.float64), torch.rand(1, 3, 32, 32, dtype=torch.float64)
    pts = _circles(2, 8, 0.3)
    rows = torch.tensor([0, 0])
    a = curve_samples(free(x, seen, pts, rows)) - curve_samples(pts)  # (N, 3k, 2)
    b = curve_samples(smooth(x, seen, pts, rows)) - curve_samples(pts)
    q = curve_samples(pts)
    tangent = q.roll(-1, 1) - q.roll(1, 1)
    tangent = tangent / tangent.norm(dim=-1, keepdim=True)
    normal = torch.stack([-tangent[..., 1], tangent[..., 0]], -1)
    across = lambda d: (d * normal).sum(-1)  # noqa: E731
    w = torch.tensor([1, 4, 6, 4, 1], dtype=torch.float64) / 16
    want = sum(w[i] * across(a).roll(2 - i, 1) for i in range(5))
    assert torch.allclose(across(b), want, atol=1e-12)
    assert torch.allclose(across(b).mean(1), across(a).mean(1), atol=1e-12)


def test_the_fitted_projection_starts_its_point_stage_from_the_moved_outlines():
    """``project``'s point stage keeps each picture's best step from its start, and that start is
    the outlines as the point passes moved them: with no point steps, exactly those."""
    from im2vec_cli.project import ProjectSettings, project_frames

    torch.manual_seed(7)
    model = Im2Vec(ModelConfig(paths=2, point_passes=1, **TINY)).eval()
    torch.nn.init.normal_(model.decoder.net[-1].weight, std=0.05)
    torch.nn.init.normal_(model.point_pass.net[-1].weight, std=0.5)
    x = _bars()
    with torch.no_grad():
        want = model.decode(model.encode(x)[0], None, x).points
    got = project_frames(model, x, ProjectSettings(latent_steps=0, code_steps=1, point_steps=0))  # one step: its start
    assert torch.allclose(got.decoded.points, want, atol=1e-6)
    assert not torch.allclose(want, model.decode(model.encode(x)[0]).points, atol=1e-4)
