"""Checkpoints are read as data, never run (issue "Safety", loading): ``weights_only`` loading,
and a file that is not a checkpoint is one error line, through `im2vec export` and the API."""

import os
import pickle
import subprocess
import sys

import pytest
import torch

from im2vec_cli.checkpoint import load_checkpoint, save_checkpoint
from im2vec_cli.errors import ModelError

EXE = [sys.executable, "-m", "im2vec_cli"]


class _Payload:
    """Unpickling this calls ``os.system`` with a command that creates a file."""

    def __init__(self, marker):
        self.marker = marker

    def __reduce__(self):
        return os.system, (f"touch {self.marker}",)


def test_a_crafted_checkpoint_runs_nothing(tmp_path):
    marker = tmp_path / "pwned"
    run = tmp_path / "run"
    run.mkdir()
    with open(run / "checkpoint.pt", "wb") as f:
        pickle.dump({"model": {}, "model_config": {}, "step": 1, "x": _Payload(marker)}, f)
    with pytest.raises(ModelError, match="refused: holds more than tensors"):
        load_checkpoint(run / "checkpoint.pt")
    r = subprocess.run(EXE + ["export", str(run), "-o", str(tmp_path / "m")], capture_output=True, text=True)
    assert r.returncode == 1 and r.stderr.startswith("Error:") and r.stderr.count("\n") == 1, r.stderr
    assert not marker.exists() and not (tmp_path / "m").exists()


@pytest.mark.parametrize("state, word", [
    ([1, 2, 3], "a list, not a dict"),
    ({"model": {}, "step": 3}, "'model_config' missing"),
    ({"model": {}, "model_config": {}, "step": "3"}, "'step' missing or not a int"),
])
def test_what_is_not_a_checkpoint_is_one_line(tmp_path, state, word):
    run = tmp_path / "run"
    run.mkdir()
    torch.save(state, run / "checkpoint.pt")
    with pytest.raises(ModelError, match=word):
        load_checkpoint(run / "checkpoint.pt")
    r = subprocess.run(EXE + ["export", str(run), "-o", str(tmp_path / "m")], capture_output=True, text=True)
    assert r.returncode == 1 and r.stderr.startswith("Error:") and r.stderr.count("\n") == 1, r.stderr
    assert "Traceback" not in r.stderr and word in r.stderr


def test_a_real_checkpoint_round_trips(tmp_path):
    state = {"model": {"w": torch.arange(6.0).view(2, 3)}, "model_config": {"latent": 8, "paths": [1, 2]}, "step": 7,
             "generator": [torch.Generator().get_state()], "torch_rng": torch.get_rng_state(), "cuda_rng": None,
             "ema": None, "optimizer": {"state": {0: {"m": torch.ones(2)}}, "lr": 1e-3}}
    save_checkpoint(tmp_path / "c.pt", state)
    back = load_checkpoint(tmp_path / "c.pt")
    assert back["step"] == 7 and torch.equal(back["model"]["w"], state["model"]["w"])
    assert torch.equal(back["generator"][0], state["generator"][0]) and back["optimizer"]["lr"] == 1e-3
