"""An install without the Makefile (issue "An install that works anywhere"): the wheel carries the
shipped models, and the installed package works from any folder as the checkout does."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.slow  # builds the wheel (35 MB) and runs the installed package in real processes
def test_the_wheel_carries_the_models_and_works_from_any_folder(tmp_path):
    """`pip install .` shipped no models: outside the checkout `vectorize` and `sample` failed with
    "unknown model 'fonts'". The wheel is built as pip builds it (setup.py's build_py), installed
    into a folder of its own (its dependencies are this environment's), and run from another
    folder: the SVG is the checkout's, byte for byte, and `sample` draws with the default model."""
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", str(REPO),
                    "-w", str(tmp_path / "wheel")], check=True, timeout=600, capture_output=True)
    (wheel,) = (tmp_path / "wheel").glob("im2vec-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for model in ("fonts", "mnist", "emoji", "icons"):
        assert {f"im2vec_cli/models/{model}/config.json", f"im2vec_cli/models/{model}/model.safetensors"} <= names
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(tmp_path / "site"),
                    str(wheel)], check=True, timeout=300, capture_output=True)
    env = {k: v for k, v in os.environ.items() if k != "IM2VEC_MODELS"}
    installed = {**env, "PYTHONPATH": str(tmp_path / "site")}
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    shutil.copy(REPO / "examples" / "glyph_a.png", elsewhere / "glyph.png")

    def im2vec(*args, cwd, environ):
        return subprocess.run([sys.executable, "-m", "im2vec_cli", *args], cwd=cwd, env=environ, capture_output=True,
                              text=True, timeout=300)

    where = subprocess.run([sys.executable, "-c", "import im2vec_cli; print(im2vec_cli.__file__)"], cwd=elsewhere,
                           env=installed, capture_output=True, text=True, check=True).stdout.strip()
    assert where.startswith(str(tmp_path / "site")), where  # the installed copy, not the checkout
    r = im2vec("vectorize", "glyph.png", "-o", "g.svg", cwd=elsewhere, environ=installed)
    assert r.returncode == 0, r.stderr
    r = im2vec("vectorize", str(elsewhere / "glyph.png"), "-o", str(tmp_path / "checkout.svg"), cwd=REPO, environ=env)
    assert r.returncode == 0, r.stderr
    assert (elsewhere / "g.svg").read_bytes() == (tmp_path / "checkout.svg").read_bytes()
    r = im2vec("sample", "--n", "2", "-o", "s", cwd=elsewhere, environ=installed)
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in (elsewhere / "s").iterdir()) == ["contact.png", "sample_0.svg", "sample_1.svg"]


def test_an_install_without_models_says_what_to_do(tmp_path, monkeypatch):
    """No models found anywhere: the error names the ways to give one (it said "shipped models: none")."""
    import im2vec_cli.config as pretrained
    from im2vec_cli.errors import ModelError

    monkeypatch.setattr(pretrained, "REPO_MODELS", tmp_path / "none")
    monkeypatch.setattr(pretrained, "PACKAGE_MODELS", tmp_path / "none")
    monkeypatch.delenv("IM2VEC_MODELS", raising=False)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ModelError, match="no models are installed; give --model a model folder, or set IM2VEC_MODELS"):
        pretrained.resolve_model("fonts")
