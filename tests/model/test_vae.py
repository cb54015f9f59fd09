import warnings

import pytest
import torch

from im2vec_cli.config import MAX_FEEDBACK, ModelConfig, TrainConfig
from im2vec_cli.errors import Im2VecError, ModelError
from im2vec_cli.model.decoder import PathDecoder
from im2vec_cli.model.pretrained import from_pretrained, save_pretrained
from im2vec_cli.model.vae import Im2Vec
from im2vec_cli.training.train import TrainState
from tests.helpers import descend

TINY = dict(image_size=32, latent=16, enc_width=8, lstm_hidden=16, code=8, dec_width=16, dec_layers=3, deform_width=8)


@pytest.mark.parametrize("k", [1, 7, 16, 25])
def test_path_decoder_keeps_length_3k(k):
    dec = PathDecoder(code=8, width=16, layers=4, deform=True, deform_width=8)
    torch.nn.init.normal_(dec.net[-1].weight)
    out = dec(torch.randn(5, 8), k)
    assert out.shape == (5, 3 * k, 2)
    assert (out >= 0).all() and (out <= 1).all()


@pytest.mark.parametrize("paths,grouping", [(1, "evenodd"), (3, "evenodd"), (3, "nonzero"), (4, "layers")])
@pytest.mark.parametrize("batch", [1, 2])
def test_model_shapes(paths, grouping, batch):
    m = Im2Vec(ModelConfig(paths=paths, grouping=grouping, **TINY))
    x = torch.rand(batch, 3, 32, 32)
    for k in (7, 12):
        dec, mu, logvar = m(x, k)
        assert dec.points.shape == (batch, paths, 3 * k, 2)
        g = paths if grouping == "layers" else 1
        assert dec.colors.shape == (batch, g, 3) and dec.depth.shape == (batch, g)
        assert mu.shape == logvar.shape == (batch, 16)
        assert m.render(dec).shape == (batch, 3, 32, 32)


def test_nonzero_grouping_keeps_overlaps_filled():
    """Two copies of one path: even-odd cancels them (a hole), nonzero draws the path once."""
    torch.manual_seed(0)
    x = torch.rand(1, 3, 32, 32)
    renders = {}
    for grouping in ("evenodd", "nonzero"):
        torch.manual_seed(0)
        m = Im2Vec(ModelConfig(paths=2, grouping=grouping, palette="#000000", **TINY))
        dec = m(x, 8, sample=False)[0]
        assert dec.fill_rule == grouping and dec.colors.shape == (1, 1, 3)
        dec.points = dec.points[:, :1].repeat(1, 2, 1, 1)  # (1, 2, 24, 2): path 0 twice
        renders[grouping] = m.render(dec, composite="over")
        one = Im2Vec(ModelConfig(paths=1, grouping=grouping, palette="#000000", **TINY))
        dec1 = one(x, 8, sample=False)[0]
        dec1.points = dec.points[:, :1]
        renders[grouping + "1"] = one.render(dec1, composite="over")
    assert renders["nonzero1"].min() < 0.2  # the path draws ink
    assert torch.allclose(renders["nonzero"], renders["nonzero1"], atol=1e-5)
    inside = renders["nonzero1"] < 0.05  # deep inside the path: even-odd cancels the copies there
    assert inside.any() and (renders["evenodd"][inside] > 0.95).all()


def test_grow_state_into_more_paths_and_another_grouping():
    from im2vec_cli.model.pretrained import grow_state

    torch.manual_seed(0)
    old = ModelConfig(paths=2, palette="#000000", **TINY)
    new = ModelConfig(paths=5, grouping="nonzero", palette="#000000", **TINY)
    state = Im2Vec(old).state_dict()
    grown = grow_state(state, old, new, seed=3)
    Im2Vec(new).load_state_dict(grown)  # strict: every key and shape fits
    step0, step1 = state["codes.step"], grown["codes.step"]
    assert step1.shape == (5, 16) and torch.equal(step1[:2], step0)
    assert not torch.equal(step1[2:4], step0) and (step1[2:4] - step0).abs().max() < 0.2
    assert all(torch.equal(v, grown[k]) for k, v in state.items() if k != "codes.step")
    with pytest.raises(ModelError, match="latent"):
        grow_state(state, old, ModelConfig(paths=2, palette="#000000", **{**TINY, "latent": 8}))


def test_grow_state_drops_a_palette_into_learned_colours():
    """A black-palette model fine-tuned into coloured layers: the palette head goes, the rest is kept."""
    from im2vec_cli.model.pretrained import grow_state

    torch.manual_seed(0)
    old = ModelConfig(paths=2, palette="#000000", **TINY)
    new = ModelConfig(paths=3, grouping="layers", palette="", **TINY)
    state = Im2Vec(old).state_dict()
    grown = grow_state(state, old, new, seed=1)
    model = Im2Vec(new)
    model.load_state_dict(grown)  # strict: every key and shape fits
    assert not any(k.startswith("palette_logits.") for k in grown) and any(k.startswith("palette_logits.") for k in state)
    assert all(torch.equal(v, grown[k]) for k, v in state.items() if k in grown and k != "codes.step")
    colors = model.decode(torch.randn(4, TINY["latent"])).colors  # learned: not the palette's black
    assert colors.shape == (4, 3, 3) and colors.min() > 0
    with pytest.raises(ModelError, match="not give it another"):
        grow_state(state, old, ModelConfig(paths=2, palette="#000000,#ff0000", **TINY))


def test_a_feedback_pass_grown_in_encodes_as_before_then_learns_from_the_render():
    """``feedback`` added by a fine-tune starts as the identity on the encoder's latent; its
    step, trained alone through the renderer, cuts the error and reads the render it is given."""
    from im2vec_cli.model.pretrained import grow_state

    torch.manual_seed(0)
    old, new = ModelConfig(palette="#000000", **TINY), ModelConfig(feedback=1, palette="#000000", **TINY)
    base = Im2Vec(old)
    torch.nn.init.normal_(base.decoder.net[-1].weight, std=0.05)  # paths that depend on z (untrained: circles)
    model = Im2Vec(new)
    model.load_state_dict(grow_state(base.state_dict(), old, new, seed=2))  # strict
    x = torch.ones(4, 3, 32, 32)
    for i, r in enumerate((4, 6, 8, 10)):
        x[i, :, 16 - r : 16 + r, 10 : 10 + r] = 0.0  # black bars of four sizes on white
    with torch.no_grad():
        assert torch.equal(model.encode(x)[0], base.encode(x)[0])

    def error() -> torch.Tensor:
        return (model.render(model.decode(model.encode(x)[0], 8)) - x).square().mean()

    before, after = descend(error, model.feedback.parameters())
    assert after < 0.97 * before  # the paths of a barely trained decoder move little with z
    with torch.no_grad():
        mu = model.encode(x)[0]
        model.render = lambda dec, **kw: torch.zeros(len(x), 3, 32, 32)  # another render: another step
        assert not torch.allclose(model.encode(x)[0], mu)
    with pytest.raises(Im2VecError, match="feedback"):
        ModelConfig(feedback=MAX_FEEDBACK + 1, **TINY)


def test_more_feedback_passes_apply_the_one_module_again():
    """A 1-pass model's weights load into a 3-pass one (``bench/ship_phase.py --feedback``),
    which applies its one ``Feedback`` module three times, each to the render of the last latent."""
    torch.manual_seed(0)
    one = Im2Vec(ModelConfig(feedback=1, palette="#000000", **TINY))
    torch.nn.init.normal_(one.feedback.step.weight, std=0.05)  # a trained step is not zero
    three = Im2Vec(ModelConfig(feedback=3, palette="#000000", **TINY))
    three.load_state_dict(one.state_dict())  # strict: the same keys
    x = torch.rand(2, 3, 32, 32)
    with torch.no_grad():
        mu = one.encoder(x)[0]
        for _ in range(3):
            mu = one.feedback(x, one.render(one.decode(mu)), mu)
        assert torch.allclose(three.encode(x)[0], mu, atol=1e-6)
        assert not torch.allclose(three.encode(x)[0], one.encode(x)[0], atol=1e-4)


def test_feedback_select_keeps_per_picture_the_guess_whose_render_is_closest():
    """``feedback_select``: outside training, each picture's latent is the one of the chain
    (the encoder's guess, then each pass's) whose render at the passes' softness is closest to
    it, the chain computed here by hand; in training it is the last pass's, as without it."""
    from im2vec_cli.model.vae import FEEDBACK_TAU

    torch.manual_seed(0)
    plain = Im2Vec(ModelConfig(feedback=4, palette="#000000", **TINY))
    torch.nn.init.normal_(plain.feedback.step.weight, std=0.3)  # passes that move the guess, some the wrong way
    torch.nn.init.normal_(plain.decoder.net[-1].weight, std=0.05)
    model = Im2Vec(ModelConfig(feedback=4, feedback_select=True, palette="#000000", **TINY))
    model.load_state_dict(plain.state_dict())  # strict: no new weights
    plain.eval(), model.eval()
    x = torch.rand(6, 3, 32, 32)
    with torch.no_grad():
        chain = [plain.encoder(x)[0]]
        for _ in range(4):
            chain.append(plain.feedback(x, plain.render(plain.decode(chain[-1]), tau=FEEDBACK_TAU), chain[-1]))
        err = torch.stack([((plain.render(plain.decode(z), tau=FEEDBACK_TAU) - x) ** 2).flatten(1).mean(1)
                           for z in chain], 1)  # (B, 5)
        pick = err.argmin(1)
        assert len(set(pick.tolist())) > 1  # the test tells pictures apart
        want = torch.stack(chain, 1)[torch.arange(len(x)), pick]
        assert torch.allclose(model.encode(x)[0], want, atol=1e-6)
        assert torch.allclose(plain.encode(x)[0], chain[-1], atol=1e-6)
        model.train()
        assert torch.allclose(model.encode(x)[0], chain[-1], atol=1e-6)
    with pytest.raises(Im2VecError, match="feedback_select"):
        ModelConfig(feedback_select=True, **TINY)


def test_per_path_inputs_grown_into_a_feedback_pass_change_nothing_until_trained():
    """``feedback_paths`` added to a feedback model by a fine-tune: its first layer gets zero
    weights for the P coverage channels, so the grown model encodes exactly as before; weights
    there make the pass read which path drew what."""
    from im2vec_cli.model.pretrained import grow_state

    torch.manual_seed(0)
    old = ModelConfig(feedback=2, palette="#000000", **TINY)
    new = ModelConfig(feedback=2, feedback_paths=True, palette="#000000", **TINY)
    base = Im2Vec(old)
    torch.nn.init.normal_(base.feedback.step.weight, std=0.05)
    torch.nn.init.normal_(base.decoder.net[-1].weight, std=0.05)
    model = Im2Vec(new)
    model.load_state_dict(grow_state(base.state_dict(), old, new, seed=3))  # strict
    assert model.feedback.net[0].weight.shape[1] == 3 * 3 + new.paths
    x = torch.rand(2, 3, 32, 32)
    with torch.no_grad():
        assert torch.allclose(model.encode(x)[0], base.encode(x)[0], atol=1e-6)
        torch.nn.init.normal_(model.feedback.net[0].weight[:, 9:], std=0.1)
        assert not torch.allclose(model.encode(x)[0], base.encode(x)[0], atol=1e-4)
    back = grow_state(model.state_dict(), new, old)  # dropped again: the picture channels stay
    assert torch.equal(back["feedback.net.0.weight"], model.feedback.net[0].weight[:, :9])
    with pytest.raises(Im2VecError, match="feedback_paths"):
        ModelConfig(feedback_paths=True, **TINY)


def test_bad_image_shape_names_the_argument():
    m = Im2Vec(ModelConfig(**TINY))
    with pytest.raises(ValueError, match="images"):
        m.encode(torch.rand(1, 3, 64, 64))


def test_palette_restricts_colours():
    m = Im2Vec(ModelConfig(palette="#000000", **TINY))
    dec, _, _ = m(torch.rand(2, 3, 32, 32), 7)
    assert torch.allclose(dec.colors, torch.zeros_like(dec.colors))


def test_sample_deformation_can_be_switched_off():
    m = Im2Vec(ModelConfig(deform=False, **TINY))
    assert m.decoder.deform is None
    assert m(torch.rand(1, 3, 32, 32), 7)[0].points.shape == (1, 4, 21, 2)


def test_save_load_round_trip(tmp_path):
    torch.manual_seed(0)
    m = Im2Vec(ModelConfig(**TINY))
    for p in m.parameters():
        p.data.normal_(0, 0.1)
    save_pretrained(m, tmp_path / "m")
    m2 = from_pretrained(tmp_path / "m")
    x = torch.rand(2, 3, 32, 32)
    m.eval()
    a, _, _ = m(x, 9, sample=False)
    b, _, _ = m2(x, 9, sample=False)
    assert torch.equal(a.points, b.points) and torch.equal(a.colors, b.colors)


def test_from_pretrained_errors(tmp_path):
    with pytest.raises(ModelError, match="unknown model"):
        from_pretrained("no-such-model")
    m = Im2Vec(ModelConfig(**TINY))
    save_pretrained(m, tmp_path / "m")
    (tmp_path / "m" / "model.safetensors").write_bytes(b"garbage")
    with pytest.raises(ModelError, match="unreadable"):
        from_pretrained(tmp_path / "m")
    save_pretrained(Im2Vec(ModelConfig(**{**TINY, "latent": 8})), tmp_path / "other")
    (tmp_path / "m" / "model.safetensors").write_bytes((tmp_path / "other" / "model.safetensors").read_bytes())
    with pytest.raises(ModelError, match="shape"):
        from_pretrained(tmp_path / "m")
    (tmp_path / "m" / "model.safetensors").unlink()
    with pytest.raises(ModelError, match="missing"):
        from_pretrained(tmp_path / "m")


def test_config_rejects_unknown_keys_and_types():
    with pytest.raises(Im2VecError, match="unknown"):
        ModelConfig.from_dict({"nope": 1})
    with pytest.raises(Im2VecError, match="latent"):
        ModelConfig.from_dict({"latent": "big"})
    assert ModelConfig.from_dict(ModelConfig(latent=7).to_dict()).latent == 7


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA (cuDNN's flat LSTM weights)")
def test_an_ema_copy_runs_on_cuda_without_the_rnn_weights_warning():
    model = Im2Vec(ModelConfig(paths=2, **TINY)).cuda()
    ema = TrainState.create(model, TrainConfig(ema=0.99), rank=0).ema.module.eval()  # AveragedModel's deepcopy
    with warnings.catch_warnings():
        warnings.filterwarnings("error", message=".*contiguous chunk of memory.*")
        with torch.no_grad():
            dec, _, _ = ema(torch.rand(2, 3, 32, 32, device="cuda"), 4)
    assert dec.points.shape == (2, 2, 12, 2)
