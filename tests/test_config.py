"""Configs (``config.py``): bounds checked before anything is built, config files read within
bounds, and a model folder's weights checked by dtype (``model/pretrained.py``)."""

import dataclasses
import json
import os

import pytest
import torch

from im2vec_cli.config import MAX_CONFIG_BYTES, MAX_RENDER_WORK, MODEL_AT_MOST, ModelConfig, read_json
from im2vec_cli.errors import ConfigError, Im2VecError, ModelError
from tests.helpers import make_tiny_model


@pytest.mark.parametrize("key", sorted(MODEL_AT_MOST))
def test_each_size_past_its_bound_is_refused_by_name(key):
    with pytest.raises(ConfigError, match=f"ModelConfig.{key} must be <= {MODEL_AT_MOST[key]}"):
        ModelConfig(**{key: MODEL_AT_MOST[key] + 1})


def test_a_config_integer_too_large_for_torch_is_a_bound_not_a_type_error():
    with pytest.raises(ConfigError, match="ModelConfig.samples must be <="):
        ModelConfig.from_dict({"samples": 2**70})


def test_a_render_beyond_its_work_bound_is_refused():
    with pytest.raises(ConfigError, match="paths x max_segments x samples x image_size"):
        ModelConfig(image_size=256, paths=64, max_segments=200, samples=32)
    ok = ModelConfig(image_size=128, paths=8, max_segments=25, samples=4)  # the paper's 128 px emoji fit easily
    assert ok.paths * ok.max_segments * ok.samples * ok.image_size**2 <= MAX_RENDER_WORK


def test_the_largest_model_the_bounds_allow_is_about_half_a_gigabyte():
    """Every width at its bound, every pass on, the largest canvas: built on the meta device
    (no memory), its parameters counted. config.py's comment quotes this figure."""
    from im2vec_cli.model import build_model

    for arch in ("im2vec", "imagevae"):
        size = MODEL_AT_MOST["image_size"]
        top = dict(MODEL_AT_MOST, image_size=size, samples=1, arch=arch, feedback=8, path_passes=8, point_passes=8,
                   grouping="layers", feedback_paths=True)
        top["max_segments"] = top["min_segments"] = top["segments"] = min(200, MAX_RENDER_WORK // (64 * size**2))
        with torch.device("meta"):
            model = build_model(ModelConfig(**top))
        params = sum(p.numel() for p in model.parameters())
        assert params <= 125e6, (arch, params)


def test_config_files_are_read_only_when_small_regular_and_utf8(tmp_path):
    good = tmp_path / "good.json"
    good.write_text(json.dumps({"latent": 64}))
    assert read_json(good) == {"latent": 64}
    sparse = tmp_path / "sparse.json"
    with open(sparse, "wb") as f:
        f.truncate(3 * 2**30)  # 3 GB that take no disk: refused from its size, unread
    with pytest.raises(Im2VecError, match="3,221,225,472 bytes, over the 1,048,576 a config file may have"):
        read_json(sparse)
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)  # nobody writes: a blocking open would wait forever
    with pytest.raises(Im2VecError, match="a FIFO, where a config file should be"):
        read_json(fifo)
    with pytest.raises(Im2VecError, match="a folder, where a config file should be"):
        read_json(tmp_path)
    binary = tmp_path / "binary.json"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)))
    with pytest.raises(Im2VecError, match="not valid JSON \\(not UTF-8 text\\)"):
        read_json(binary)
    assert MAX_CONFIG_BYTES == 2**20


def test_a_model_folder_with_huge_sizes_is_refused_before_it_is_built(tmp_path):
    from im2vec_cli.model.pretrained import from_pretrained

    folder = make_tiny_model(tmp_path / "m")
    cfg = json.loads((tmp_path / "m" / "config.json").read_text())
    (tmp_path / "m" / "config.json").write_text(json.dumps({**cfg, "samples": 10**6}))
    with pytest.raises(Im2VecError, match="samples must be <= 32"):
        from_pretrained(folder)


def test_weights_of_another_dtype_are_refused_by_name(tmp_path):
    """int8 weights would be cast to float and drawn as nonsense: refused, naming the tensor; fp16
    storage (``save_pretrained(half=True)``) stays accepted."""
    from safetensors.torch import load_file, save_file

    from im2vec_cli.model.pretrained import from_pretrained

    folder = make_tiny_model(tmp_path / "m")
    weights = tmp_path / "m" / "model.safetensors"
    state = load_file(str(weights))
    save_file({k: v.half() if v.is_floating_point() else v for k, v in state.items()}, str(weights))
    from_pretrained(folder)
    name = sorted(k for k, v in state.items() if v.is_floating_point())[0]
    save_file({**state, name: state[name].to(torch.int8)}, str(weights))
    with pytest.raises(ModelError, match=f"{name} is stored as int8, the model holds float32"):
        from_pretrained(folder)


def test_model_config_bounds_cover_only_its_integer_fields():
    ints = {f.name for f in dataclasses.fields(ModelConfig) if f.type in ("int", int)}
    assert set(MODEL_AT_MOST) <= ints
