"""The neighbour prior (model/prior.py ``NeighbourPrior``): draws between the latents of training
pictures that look alike, stored beside the model and preferred by ``sample``."""

import json
import shutil

import numpy as np
import pytest
import torch

import im2vec_cli as iv
from im2vec_cli.data.folder import load_folder
from im2vec_cli.errors import ConfigError, ModelError
from im2vec_cli.infer import resolve_prior
from im2vec_cli.model.pretrained import save_pretrained
from im2vec_cli.model.prior import (
    NEIGHBOURS_CONFIG,
    NEIGHBOURS_WEIGHTS,
    NeighbourPrior,
    fit_neighbours,
    fit_prior,
    posterior_means,
)
from tests.helpers import make_tiny_model, run
from tests.model.test_prior import _labelled_folder


def _points(n=300, d=6, seed=0):
    return torch.randn(n, d, generator=torch.Generator().manual_seed(seed)) * 3


def test_neighbours_are_the_nearest_others_and_draws_lie_between_them():
    x = _points()
    prior = fit_neighbours(x, 4, seed=1)
    a = prior.anchors
    assert torch.equal(a, x.half().float())  # all kept (fewer than max_anchors), as stored
    brute = [sorted(((a[i] - a[j]).norm().item(), j) for j in range(len(a)) if j != i)[:4] for i in range(len(a))]
    assert [sorted(r.tolist()) for r in prior.neighbours] == [sorted(j for _, j in b) for b in brute]
    z = prior.sample(500, seed=3)
    # each draw is a + u (b - a) with b a neighbour of a and u in [0, 1/2]: find its segment
    for v in z[:60]:
        i = int((a - v).norm(dim=1).argmin())
        seg = a[prior.neighbours[i]] - a[i]  # (k, D)
        u = ((v - a[i]) * seg).sum(1) / seg.square().sum(1)
        off = (a[i] + u[:, None] * seg - v).norm(dim=1)
        assert float(off.min()) < 1e-4 and -1e-5 <= float(u[off.argmin()]) <= 0.5 + 1e-5
    assert torch.equal(prior.sample(7, seed=3), prior.sample(7, seed=3))
    assert not torch.equal(prior.sample(7, seed=4), prior.sample(7, seed=3))
    cold = prior.sample(50, seed=2, temperature=0.0)  # the training latents themselves
    assert bool((cold[:, None] == a[None]).all(-1).any(1).all())


def test_a_subset_of_anchors_bounds_the_stored_size():
    x = _points(500)
    prior = fit_neighbours(x, 3, seed=0, max_anchors=100)
    assert prior.anchors.shape == (100, 6) and prior.config.anchors == 100 and prior.config.images == 500
    assert bool((prior.anchors[:, None] == x.half().float()[None]).all(-1).any(1).all())  # a subset, not a summary
    assert torch.equal(fit_neighbours(x, 3, seed=0, max_anchors=100).anchors, prior.anchors)
    for k in (0, 100):
        with pytest.raises(ValueError, match="neighbours must be in"):
            fit_neighbours(x, k, max_anchors=100)


def test_save_and_load_draw_the_same_and_a_bad_file_is_refused(tmp_path):
    prior = fit_neighbours(_points(), 5, seed=2)
    prior.save(tmp_path)
    back = NeighbourPrior.load(tmp_path)
    assert back.config == prior.config and torch.equal(back.sample(40, seed=1), prior.sample(40, seed=1))
    (tmp_path / NEIGHBOURS_WEIGHTS).write_bytes(b"garbage")
    with pytest.raises(ModelError, match="unreadable neighbour prior"):
        NeighbourPrior.load(tmp_path)
    assert NeighbourPrior.load(tmp_path / "none") is None


@pytest.fixture
def two_priors(tmp_path):
    """A tiny model folder storing both priors, on latents far from N(0, I) and from each other."""
    folder = make_tiny_model(tmp_path / "tiny")
    m = iv.load_model(str(folder), "cpu")
    m.latent_prior = fit_prior(_points(200, m.config.latent) + 3.0, 2)
    m.neighbour_prior = fit_neighbours(_points(200, m.config.latent) - 3.0, 5)
    return save_pretrained(m, tmp_path / "both"), folder


def test_sample_prefers_the_neighbours_and_each_prior_can_be_asked_for(two_priors, tmp_path):
    both, bare = two_priors
    m = iv.load_model(str(both), "cpu")
    assert resolve_prior(m) == "neighbours"
    z = iv.prior_latents(300, m, seed=4)
    assert np.array_equal(z, m.neighbour_prior.sample(300, seed=4).numpy())
    assert np.array_equal(z, iv.prior_latents(300, m, seed=4, prior="neighbours"))
    assert float(z.mean()) < -1 and float(iv.prior_latents(300, m, seed=4, prior="fitted").mean()) > 1
    with pytest.raises(ModelError, match="no neighbour prior"):
        iv.prior_latents(3, iv.load_model(str(bare), "cpu"), prior="neighbours")
    out = tmp_path / "s"
    assert run(["sample", "--n", "2", "--seed", "3", "--model", str(both), "-o", str(out)]).exit_code == 0
    assert [p.read_text() for p in sorted(out.glob("*.svg"))] == [v.to_svg() for v in iv.sample(2, m, seed=3)]
    res = run(["sample", "--n", "2", "--prior", "neighbours", "--model", str(bare), "-o", str(tmp_path / "t")])
    assert res.exit_code != 0 and "fit-prior --neighbours" in res.output and "Traceback" not in res.output


def test_fit_prior_writes_the_neighbours_and_drops_stale_ones(two_priors, tmp_path):
    both, _ = two_priors
    data = _labelled_folder(tmp_path / "data")
    own = tmp_path / "own"
    shutil.copytree(both, own)
    res = run(["fit-prior", str(data), "--model", str(own), "--components", "2", "--neighbours", "3",
               "-o", str(own), "--overwrite"])
    assert res.exit_code == 0, res.output
    m = iv.load_model(str(own), "cpu")
    cfg = json.loads((own / NEIGHBOURS_CONFIG).read_text())
    assert cfg["neighbours"] == 3 and cfg["images"] == cfg["anchors"] == 90
    x, _ = load_folder(data / "train", m.config.image_size, fit=m.config.fit)
    assert torch.allclose(m.neighbour_prior.anchors, posterior_means(m, x).half().float(), atol=1e-3)  # these weights'
    res = run(["fit-prior", str(data), "--model", str(own), "--components", "2", "--neighbours", "0",
               "-o", str(own), "--overwrite"])
    assert res.exit_code == 0, res.output
    assert not (own / NEIGHBOURS_WEIGHTS).exists() and not (own / NEIGHBOURS_CONFIG).exists()
    assert iv.load_model(str(own), "cpu").neighbour_prior is None
    with pytest.raises(ConfigError, match="neighbours 90: fewer than the 90 images"):  # checked before the work
        iv.fit_prior(data, str(own), str(tmp_path / "x"), neighbours=90)
    assert not (tmp_path / "x").exists()


def test_train_fits_the_neighbours_and_export_keeps_them_for_those_weights_only(tmp_path):
    from im2vec_cli.model.pretrained import export_checkpoint
    from im2vec_cli.training.train import train
    from tests.helpers import synthetic_shapes
    from tests.test_train import MODEL, fast_cfg

    run_dir = tmp_path / "run"
    out = train(None, run_dir, MODEL, fast_cfg(steps=2), images=synthetic_shapes(40, 32))  # 32 train, 8 val
    m = iv.load_model(str(out), "cpu")
    assert m.neighbour_prior.config.step == 2 and m.neighbour_prior.config.neighbours == 8
    assert m.neighbour_prior.anchors.shape == (32, m.config.latent)
    exported, _ = export_checkpoint(run_dir, tmp_path / "exp")
    assert NeighbourPrior.load(exported).config == m.neighbour_prior.config
    cfg = json.loads((run_dir / NEIGHBOURS_CONFIG).read_text())
    (run_dir / NEIGHBOURS_CONFIG).write_text(json.dumps({**cfg, "step": 1}))  # fitted to other weights
    again, _ = export_checkpoint(run_dir, tmp_path / "exp2")
    assert NeighbourPrior.load(again) is None and (again / "latent_prior.json").is_file()
    none = train(None, tmp_path / "r0", MODEL, fast_cfg(steps=2, prior_neighbours=0), images=synthetic_shapes(40, 32))
    assert iv.load_model(str(none), "cpu").neighbour_prior is None and iv.load_model(str(none), "cpu").latent_prior


def test_fit_neighbours_alone_fits_what_fit_prior_fits_and_keeps_the_mixture(two_priors, tmp_path):
    both, _ = two_priors
    data = _labelled_folder(tmp_path / "data")
    full = iv.fit_prior(data, str(both), str(tmp_path / "full"), components=2, neighbours=3, seed=5)
    assert full.config.images == 90
    seen = []
    alone = iv.fit_neighbours(data, str(both), str(tmp_path / "alone"), neighbours=3, seed=5,
                              on_event=lambda e: seen.append(getattr(e, "images", None)))
    ref = NeighbourPrior.load(tmp_path / "full")
    assert alone.config == ref.config and torch.allclose(alone.anchors, ref.anchors, atol=1e-3)
    assert torch.equal(alone.neighbours, ref.neighbours) and seen[-1] == 90  # all 90 are anchors here
    kept = iv.load_model(str(tmp_path / "alone"), "cpu")
    assert torch.equal(kept.latent_prior.means, iv.load_model(str(both), "cpu").latent_prior.means)  # mixture as stored
    with pytest.raises(ConfigError, match="neighbours 0"):
        iv.fit_neighbours(data, str(both), str(tmp_path / "x"), neighbours=0)
