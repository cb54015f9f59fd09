"""The path pass (``ModelConfig.path_passes``, ``model.encoder.PathPass``): a render-and-compare
correction of each path's code and colour, checked against the chain computed by hand."""

import dataclasses

import pytest
import torch

from im2vec_cli.config import MAX_FEEDBACK, ModelConfig, TrainConfig
from im2vec_cli.errors import Im2VecError, ModelError
from im2vec_cli.model.losses import reconstruction_loss
from im2vec_cli.model.pretrained import from_pretrained, grow_state, save_pretrained
from im2vec_cli.model.vae import COLOR_RIDGE, COLOR_TAU, FEEDBACK_TAU, Im2Vec
from im2vec_cli.project import GUESS, LATENT, project_frames
from im2vec_cli.raster import gaussian_pyramid, pyramid_l2, render_coverage, render_pyramid, solve_colors, solve_order
from im2vec_cli.training.distill import freeze
from im2vec_cli.training.train import _build
from tests.helpers import descend

TINY = dict(image_size=32, latent=16, enc_width=8, lstm_hidden=16, code=8, dec_width=16, dec_layers=3, deform_width=8,
            path_pass_width=8)


def _bars() -> torch.Tensor:
    x = torch.ones(4, 3, 32, 32)
    for i, r in enumerate((4, 6, 8, 10)):
        x[i, :, 16 - r : 16 + r, 10 : 10 + r] = 0.0  # black bars of four sizes on white
    return x


def _moving(model: Im2Vec, std: float = 0.05) -> Im2Vec:
    """Paths that depend on their codes (an untrained decoder draws circles)."""
    torch.nn.init.normal_(model.decoder.net[-1].weight, std=std)
    return model


def test_a_path_pass_grown_in_draws_as_before_then_learns_alone():
    """Added by a fine-tune, the pass changes nothing; trained alone (``train_only="path_pass"``,
    every other weight frozen) through the renderer it cuts the error, and it reads its render."""
    torch.manual_seed(0)
    old, new = ModelConfig(grouping="layers", paths=3, **TINY), ModelConfig(grouping="layers", paths=3, path_passes=1,
                                                                            **TINY)
    base = _moving(Im2Vec(old))
    model = Im2Vec(new)
    model.load_state_dict(grow_state(base.state_dict(), old, new, seed=2))  # strict
    x = _bars()
    with torch.no_grad():
        mu = model.encode(x)[0]
        a, b = base.decode(mu, 8), model.decode(mu, 8, x)
        assert torch.equal(a.points, b.points) and torch.allclose(a.colors, b.colors, atol=1e-6)
    freeze(model, TrainConfig(train_only="path_pass").train_only)
    learning = [n for n, p in model.named_parameters() if p.requires_grad]
    assert learning and all(n.startswith("path_pass.") for n in learning)

    def error() -> torch.Tensor:
        return (model.render(model.decode(mu, 8, x)) - x).square().mean()

    before, after = descend(error, [p for p in model.parameters() if p.requires_grad])
    assert after < 0.9 * before
    with torch.no_grad():
        assert torch.equal(model.decode(mu, 8).points, a.points)  # without the pictures: z's own paths
        pts = model.decode(mu, 8, x).points
        model.render = lambda dec, **kw: torch.zeros(len(x), 3, 32, 32)  # another render: another step
        assert not torch.allclose(model.decode(mu, 8, x).points, pts)


def test_path_passes_chain_and_select_the_closest_by_hand():
    """Two passes, each on the render and coverage of the last codes; with ``feedback_select``
    (outside training) each picture keeps the codes and colours whose render is closest to it."""
    torch.manual_seed(1)
    cfg = dict(grouping="layers", paths=3, feedback=1, path_passes=2, **TINY)
    plain = _moving(Im2Vec(ModelConfig(**cfg)), std=0.1)
    torch.nn.init.normal_(plain.path_pass.step[-1].weight, std=0.3)  # passes that move, some the wrong way
    model = Im2Vec(ModelConfig(feedback_select=True, **cfg))
    model.load_state_dict(plain.state_dict())
    plain.eval(), model.eval()
    x = torch.rand(6, 3, 32, 32)
    with torch.no_grad():
        z = plain.encode(x)[0]
        code, depth, color, _ = plain.codes(z)
        chain = [(code, color)]
        for _ in range(2):
            pts = plain.path_points(chain[-1][0], 12)
            seen = plain.render(plain.draw(chain[-1][0], depth, chain[-1][1], 12), tau=FEEDBACK_TAU)
            parts = render_coverage(pts, size=32, tau=FEEDBACK_TAU, samples=plain.config.samples)
            chain.append(plain.path_pass(x, seen, parts, *chain[-1]))
        err = torch.stack([(plain.render(plain.draw(c, depth, k, 12), tau=FEEDBACK_TAU) - x)
                           .square().flatten(1).mean(1) for c, k in chain], 1)  # (B, 3)
        pick = err.argmin(1)
        assert len(set(pick.tolist())) > 1  # the test tells pictures apart
        want = torch.stack([c for c, _ in chain], 1)[torch.arange(len(x)), pick]
        assert torch.allclose(model.path_state(z, x)[0], want, atol=1e-6)
        assert torch.allclose(plain.path_state(z, x)[0], chain[-1][0], atol=1e-6)
        assert torch.allclose(plain.path_state(z, x)[2], chain[-1][1], atol=1e-6)
        model.train()
        assert torch.allclose(model.path_state(z, x)[0], chain[-1][0], atol=1e-6)


def test_a_palette_keeps_its_colours_and_bounds_are_checked(tmp_path):
    torch.manual_seed(2)
    model = _moving(Im2Vec(ModelConfig(palette="#000000", path_passes=1, **TINY)))
    torch.nn.init.normal_(model.path_pass.step[-1].weight, std=0.3)
    x = _bars()
    with torch.no_grad():
        z = model.encode(x)[0]
        dec = model.decode(z, 8, x)
        assert torch.equal(dec.colors, model.decode(z, 8).colors)
        assert not torch.allclose(dec.points, model.decode(z, 8).points)
    save_pretrained(model, tmp_path / "m")
    back = from_pretrained(tmp_path / "m")
    assert back.config.path_passes == 1
    with torch.no_grad():
        assert torch.allclose(back.decode(z, 8, x).points, dec.points, atol=1e-6)
    with pytest.raises(Im2VecError, match="path_passes"):
        ModelConfig(path_passes=MAX_FEEDBACK + 1, **TINY)
    with pytest.raises(Im2VecError, match="path_pass_width"):
        ModelConfig(**{**TINY, "path_pass_width": 12})
    old = ModelConfig(path_passes=1, **TINY)
    with pytest.raises(ModelError, match="path_pass_width"):
        grow_state(Im2Vec(old).state_dict(), old, ModelConfig(**{**TINY, "path_passes": 1, "path_pass_width": 16}))
    plain = ModelConfig(**TINY)
    Im2Vec(plain).load_state_dict(grow_state(model.state_dict(), old, plain))  # strict: the pass dropped


def test_projection_starts_from_the_path_passes_only_from_the_guess():
    """``GUESS`` is what ``decode`` draws with the pictures; a fitted latent's codes are its own."""
    torch.manual_seed(3)
    model = _moving(Im2Vec(ModelConfig(grouping="layers", paths=2, path_passes=1, **TINY))).eval()
    torch.nn.init.normal_(model.path_pass.step[-1].weight, std=0.3)
    x = _bars()
    with torch.no_grad():
        want = model.decode(model.encode(x)[0], None, x)
    got = project_frames(model, x, GUESS)
    assert torch.allclose(got.decoded.points, want.points, atol=1e-6)
    assert torch.allclose(got.decoded.colors, want.colors, atol=1e-6)
    fitted = project_frames(model, x, LATENT)
    with torch.no_grad():
        assert torch.allclose(fitted.decoded.points, model.decode(fitted.z).points, atol=1e-6)


def test_solved_colours_draw_closer_to_the_picture_outside_training_only():
    """``solve_colors``: given the picture, the layers' colours are those whose exact render
    (``composite_over``) is closest to it; the shapes and the training forward stay as they were."""
    torch.manual_seed(4)
    x = 1 - (1 - _bars()) * torch.tensor([0.1, 0.7, 0.9]).view(1, 3, 1, 1)  # orange bars: not what the heads guess
    plain = _moving(Im2Vec(ModelConfig(grouping="layers", paths=3, **TINY))).eval()
    solved = Im2Vec(ModelConfig(grouping="layers", paths=3, solve_colors=True, **TINY)).eval()
    solved.load_state_dict(plain.state_dict())
    z = plain.encode(x)[0]
    with torch.no_grad():
        a, b = plain.decode(z, images=x), solved.decode(z, images=x)
        err = lambda colors: float((plain.render(dataclasses.replace(a, colors=colors), tau=COLOR_TAU, composite="over")  # noqa: E731
                                    - x).pow(2).mean())
        nudged = [b.colors + 0.05 * torch.randn_like(b.colors) for _ in range(8)]
        assert torch.equal(a.points, b.points)
        assert all(torch.equal(u, v) for u, v in zip(solved.path_state(z, x, colors=False), plain.path_state(z, x)))
        assert err(b.colors) < 0.9 * err(a.colors)
        assert all(err(b.colors) <= err(c.clamp(0, 1)) for c in nudged)  # a least-squares minimum
    solved.train()
    torch.manual_seed(5)
    c = solved.decode(z, images=x).colors
    plain.train()
    torch.manual_seed(5)
    assert torch.equal(c, plain.decode(z, images=x).colors)


def test_a_solved_loss_trains_the_shapes_through_the_colour_solve():
    """``TrainConfig.solved``: in training too the colours are the solved ones, the loss renders
    them "over" as the SVG does, and its gradient reaches the path pass through the solve."""
    torch.manual_seed(6)
    x = 1 - (1 - _bars()) * torch.tensor([0.1, 0.7, 0.9]).view(1, 3, 1, 1)
    cfg = ModelConfig(grouping="layers", paths=3, path_passes=1, solve_colors=True, **TINY)
    model = _moving(Im2Vec(cfg)).train()
    torch.nn.init.normal_(model.path_pass.step[-1].weight, std=0.01)  # a pass that moves the paths
    z = model.encode(x)[0]
    torch.manual_seed(7)
    code, depth, prior = model.path_state(z, x)  # training, not solved: the network's colours
    torch.manual_seed(7)
    solved = model.path_state(z, x, solve=True)[2]
    cover = render_coverage(model.path_points(code, cfg.segments), size=32, tau=COLOR_TAU, samples=cfg.samples)
    assert torch.allclose(solved, solve_colors(cover, depth, x, prior, COLOR_RIDGE), atol=1e-6)
    assert not torch.allclose(solved, prior, atol=1e-3)
    freeze(model, "path_pass")
    torch.manual_seed(8)
    loss = reconstruction_loss(model, x, cfg.segments, 0.5, sample=False, solved=True)[0]
    torch.manual_seed(8)
    by_hand = pyramid_l2(render_pyramid(*_drawn(model, z, x), size=32, levels=cfg.levels, tau=0.5, samples=cfg.samples,
                                        composite="over"), gaussian_pyramid(x, cfg.levels))
    assert torch.allclose(loss, by_hand, atol=1e-6)
    loss.backward()
    assert all(p.grad is not None and p.grad.abs().sum() > 0 for p in model.path_pass.parameters())
    with pytest.raises(Im2VecError, match="solve_colors"):
        _build(dataclasses.replace(cfg, solve_colors=False), TrainConfig(solved=True), torch.device("cpu"), None)


def _drawn(model: Im2Vec, z: torch.Tensor, x: torch.Tensor):
    dec = model.decode(z, images=x, solve=True)
    return dec.points, dec.colors, dec.depth


def test_a_solved_order_draws_no_farther_from_the_picture_outside_training_only():
    """``solve_order``: the layers reordered (their depths' own values) as ``raster.solve_order``
    finds from the network's order and colours; a picture drawn by the model's own paths in the
    reverse order is drawn again; in training the network's order stays."""
    torch.manual_seed(3)
    cfg = ModelConfig(grouping="layers", paths=3, **TINY)
    plain = _moving(Im2Vec(cfg), std=1.0).eval()
    torch.nn.init.normal_(plain.decoder.net[-1].bias, std=1.0)  # large overlapping paths: their order matters
    colors, order = (Im2Vec(dataclasses.replace(cfg, solve_colors=True, solve_order=o)).eval() for o in (False, True))
    colors.load_state_dict(plain.state_dict())
    order.load_state_dict(plain.state_dict())
    with torch.no_grad():
        z = plain.encode(_bars())[0]
        drawn = plain.decode(z)
        hues = torch.tensor([[0.9, 0.2, 0.1], [0.1, 0.6, 0.2], [0.2, 0.3, 0.9]]).expand(4, -1, -1)
        x = plain.render(dataclasses.replace(drawn, colors=hues, depth=-drawn.depth), tau=COLOR_TAU, composite="over")
        code, depth, prior = plain.path_state(z, x)
        cover = render_coverage(plain.path_points(code, cfg.segments), size=32, tau=COLOR_TAU, samples=cfg.samples)
        a, b = colors.decode(z, images=x), order.decode(z, images=x)
        assert torch.equal(b.depth, solve_order(cover, depth, x, prior, COLOR_RIDGE))
        assert torch.equal(a.points, b.points) and torch.equal(a.depth.sort(1).values, b.depth.sort(1).values)
        err = lambda d: (plain.render(d, tau=COLOR_TAU, composite="over") - x).pow(2).flatten(1).mean(1)  # noqa: E731
        assert float(err(b).max()) < 0.1 * float(err(a).min())  # every picture drawn again, near exactly
        order.train()
        torch.manual_seed(10)
        c = order.decode(z, images=x, solve=True)
        colors.train()
        torch.manual_seed(10)
        assert torch.equal(c.depth, colors.decode(z, images=x, solve=True).depth)
