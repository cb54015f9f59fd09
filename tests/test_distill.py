"""Distillation phases (``distill``): the encoder learns the latents ``project`` fits; and
phases bounded in time (``train(minutes=...)``)."""

import dataclasses
import json

import pytest
import torch

from im2vec_cli.config import TrainConfig
from im2vec_cli.errors import ConfigError, Im2VecError
from im2vec_cli.events import Teaching, TimeUp
from im2vec_cli.model.pretrained import from_pretrained as load_pretrained
from im2vec_cli.model.vae import Im2Vec
from im2vec_cli.project import GUESS, LATENT, project
from im2vec_cli.training.distill import TEACHER_FILE, Teacher, distill_loss, fit_teacher
from im2vec_cli.training.train import train
from tests.helpers import synthetic_shapes
from tests.test_train import MODEL, fast_cfg


@pytest.fixture(scope="module")
def shapes():
    return synthetic_shapes(64, 32)


@pytest.fixture(scope="module")
def trained(tmp_path_factory, shapes):
    """A briefly trained model (the starting point of a distillation phase)."""
    run = tmp_path_factory.mktemp("base")
    return train(None, run / "run", MODEL, fast_cfg(steps=60, batch=16, lr=5e-3, beta=0.0), images=shapes)


def _fit_l2(model, images, settings):
    """Per-picture L2 at the model's size of what ``project`` fits with ``settings``."""
    p = project(model, list(images.float() / 255), settings)
    with torch.no_grad():
        img = model.render(p.decoded, composite="over", tau=0.5)
    return ((img - images.float() / 255) ** 2).flatten(1).mean(1)


def test_teacher_latents_draw_the_pictures_better_than_the_guess(trained, shapes):
    model = load_pretrained(trained)
    x = shapes[:20]
    teacher = fit_teacher(model, x, 12, seed=3)
    assert teacher.index.tolist() == sorted(set(teacher.index.tolist())) and len(teacher.index) == 12
    assert teacher.z.shape == (12, MODEL.latent)
    sub = x[teacher.index]
    with torch.no_grad():
        guess = model.encode(sub.float() / 255)[0]
    assert not torch.allclose(teacher.z, guess, atol=1e-3)  # the fit moved the latents
    # the same fit as project.LATENT's (which `encode --fit` uses), and better than the guess on most pictures
    assert torch.allclose(teacher.z, project(model, list(sub.float() / 255), LATENT).z, atol=1e-5)
    fitted, first = _fit_l2(model, sub, LATENT), _fit_l2(model, sub, GUESS)
    assert (fitted < first).float().mean() >= 0.75, (fitted, first)
    assert fitted.mean() < 0.97 * first.mean()


def test_teacher_file_roundtrip_and_bad_file(tmp_path):
    t = Teacher(torch.tensor([1, 5, 7]), torch.randn(3, 4))
    t.save(tmp_path / TEACHER_FILE)
    back = Teacher.load(tmp_path / TEACHER_FILE)
    assert torch.equal(back.index, t.index) and torch.equal(back.z, t.z)
    (tmp_path / "bad.safetensors").write_bytes(b"not a tensor file")
    with pytest.raises(Im2VecError, match="not a teacher file"):
        Teacher.load(tmp_path / "bad.safetensors")
    idx, z = t.draw(8, torch.Generator().manual_seed(0))
    assert all(int(i) in (1, 5, 7) for i in idx)
    assert torch.equal(z, t.z[[t.index.tolist().index(int(i)) for i in idx]])
    assert distill_loss(z, z) == 0 and distill_loss(z + 1, z) == pytest.approx(1.0)


def test_distillation_teaches_the_encoder_and_keeps_the_decoder(tmp_path, trained, shapes):
    """An encoder-only phase: the decoder's weights do not move, the encoder's mu comes closer
    to the fitted latents, and a resumed run learns the same (saved) targets."""
    start = load_pretrained(trained)
    cfg = fast_cfg(steps=40, batch=16, lr=2e-3, beta=0.0, distill=1.0, distill_images=24, train_only="encoder",
                   ckpt_every=20, log_every=5)
    events = []
    out = train(None, tmp_path / "run", MODEL, cfg, images=shapes, init_state=start.state_dict(),
                on_event=events.append)
    taught = [e for e in events if isinstance(e, Teaching)]
    assert taught and taught[-1].done == taught[-1].images == 24
    end = load_pretrained(out)
    for name, p in start.state_dict().items():
        same = torch.equal(p, end.state_dict()[name])
        assert same != name.startswith("encoder."), name  # the encoder learned, the rest is as it was
    teacher = Teacher.load(tmp_path / "run" / TEACHER_FILE)
    x = shapes[teacher.index].float() / 255
    with torch.no_grad():
        before = distill_loss(start.encode(x)[0], teacher.z)
        after = distill_loss(end.encode(x)[0], teacher.z)
    assert after < 0.7 * before, (before, after)
    logged = [json.loads(s) for s in (tmp_path / "run" / "metrics.jsonl").read_text().splitlines()]
    assert all("distill" in e for e in logged if e["event"] == "train")
    assert [e["done"] for e in logged if e["event"] == "teach"] == [24]  # in the run's record, with its time
    # a resumed run reads the saved teacher and never fits it again
    events.clear()
    train(None, tmp_path / "run", MODEL, TrainConfig.from_dict({**cfg.to_dict(), "steps": 45}),
          images=shapes, resume=True, on_event=events.append)
    assert not [e for e in events if isinstance(e, Teaching)]
    assert torch.equal(Teacher.load(tmp_path / "run" / TEACHER_FILE).z, teacher.z)


def test_a_bad_teacher_file_on_resume_is_an_error(tmp_path, trained, shapes):
    cfg = fast_cfg(steps=4, batch=8, distill=1.0, distill_images=8, ckpt_every=2)
    train(None, tmp_path / "run", MODEL, cfg, images=shapes, init_state=load_pretrained(trained).state_dict())
    Teacher(torch.tensor([0, 10_000]), torch.zeros(2, MODEL.latent)).save(tmp_path / "run" / TEACHER_FILE)
    with pytest.raises(Im2VecError, match="not this run's training images"):
        train(None, tmp_path / "run", MODEL, TrainConfig.from_dict({**cfg.to_dict(), "steps": 6}), images=shapes,
              resume=True)


def test_minutes_end_a_phase_at_the_step_reached_and_resume_goes_on(tmp_path, shapes):
    events = []
    cfg = fast_cfg(steps=10_000, ckpt_every=1000, val_every=1000)
    out = train(None, tmp_path / "run", MODEL, cfg, images=shapes, minutes=0.05, on_event=events.append)
    up = [e for e in events if isinstance(e, TimeUp)]
    assert len(up) == 1 and 0 < up[0].step < 10_000 and up[0].steps == 10_000
    assert (out / "model.safetensors").is_file()  # exported as it was
    state = torch.load(tmp_path / "run" / "checkpoint.pt", weights_only=True)
    assert state["step"] == up[0].step  # checkpointed at the last step, though ckpt_every was not due
    logged = [json.loads(s) for s in (tmp_path / "run" / "metrics.jsonl").read_text().splitlines()]
    assert [e["step"] for e in logged if e["event"] == "val"][-1] == up[0].step
    events.clear()
    train(None, tmp_path / "run", MODEL, fast_cfg(steps=up[0].step + 2, ckpt_every=1000, val_every=1000),
          images=shapes, resume=True, on_event=events.append)
    assert torch.load(tmp_path / "run" / "checkpoint.pt", weights_only=True)["step"] == up[0].step + 2
    assert not [e for e in events if isinstance(e, TimeUp)]


@pytest.mark.parametrize("bad", [{"train_only": "decoder"}, {"distill": -1.0}, {"distill_images": 0}])
def test_bad_distillation_settings_are_refused(bad):
    with pytest.raises(ConfigError):
        TrainConfig(**bad)


def test_the_model_built_fresh_is_untouched_by_freeze():
    """``freeze("")`` leaves every weight learning (a plain run)."""
    from im2vec_cli.training.distill import freeze

    m = Im2Vec(MODEL)
    freeze(m, "encoder")
    assert {n.split(".")[0] for n, p in m.named_parameters() if p.requires_grad} == {"encoder"}
    freeze(m, "")
    assert all(p.requires_grad for p in m.parameters())


def test_distilling_an_imagevae_is_refused_before_the_run_folder_changes(tmp_path, shapes):
    """``--arch imagevae`` has no paths to fit: one error, and the run already there is kept."""
    run = tmp_path / "run"
    train(None, run, MODEL, fast_cfg(steps=2), images=shapes)
    before = {p: p.read_bytes() for p in run.rglob("*") if p.is_file()}
    vae = dataclasses.replace(MODEL, arch="imagevae")
    with pytest.raises(Im2VecError, match="imagevae has none"):
        train(None, run, vae, fast_cfg(steps=2, distill=1.0), images=shapes, overwrite=True)
    assert {p: p.read_bytes() for p in run.rglob("*") if p.is_file()} == before


def _ddp_teacher(rank, world, model_dir, images, port, out):
    """A DDP rank (gloo) that fits its share of the teacher, and asks ``_past`` off and on a logging step."""
    import torch.distributed as dist

    import im2vec_cli.training.distill as distill
    from im2vec_cli.training.train import _past

    dist.init_process_group("gloo", init_method=f"tcp://127.0.0.1:{port}", rank=rank, world_size=world)
    try:
        torch.set_num_threads(1)
        distill.TEACHER_BATCH = 4  # 3 batches of 4: rank 0 fits two, rank 1 one
        model = load_pretrained(model_dir)
        counted = []
        teacher = fit_teacher(model, images, 12, seed=3, on_progress=lambda d, n: counted.append((d, n)),
                              rank=rank, world=world)
        past = rank == 1  # only rank 1's deadline has passed: every rank must stop, at a logging step only
        at = [_past(-1.0 if past else 1e18, step, 5, world, model) for step in (3, 5)]
        torch.save({"index": teacher.index, "z": teacher.z, "counted": counted, "past": at}, out / f"{rank}.pt")
    finally:
        dist.destroy_process_group()


def test_ddp_ranks_share_the_teachers_fit_and_gather_the_same_teacher(tmp_path, trained, shapes, monkeypatch):
    import socket

    import im2vec_cli.training.distill as distill

    monkeypatch.setattr(distill, "TEACHER_BATCH", 4)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # as the ranks: the same reduction order, so only the split into ranks differs
    try:
        alone = fit_teacher(load_pretrained(trained), shapes[:20], 12, seed=3)
    finally:
        torch.set_num_threads(threads)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    torch.multiprocessing.spawn(_ddp_teacher, args=(2, str(trained), shapes[:20], port, tmp_path), nprocs=2)
    for rank, share in ((0, 8), (1, 4)):
        got = torch.load(tmp_path / f"{rank}.pt", weights_only=True)
        assert torch.equal(got["index"], alone.index)
        assert torch.allclose(got["z"], alone.z, atol=1e-5)  # the same batches, fitted on two processes
        assert got["counted"][-1] == (share, share)  # each rank fitted its own share only
        assert got["past"] == [False, True]  # not asked at step 3; at step 5 rank 1's deadline stops both
