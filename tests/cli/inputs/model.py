"""Bad model folders and names, for any command that loads a model (builders as in
``vectorize.py``)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import torch

from tests.helpers import TINY, png


def in_unknown_model(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", "no-such-model"], None


def _model_copy(d, m):
    dst = d / "model"
    dst.mkdir()
    for f in Path(m).iterdir():
        (dst / f.name).write_bytes(f.read_bytes())
    return dst


def in_model_missing_weights(d, m):
    dst = _model_copy(d, m)
    (dst / "model.safetensors").unlink()
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(dst)], None


def in_model_truncated_weights(d, m):
    dst = _model_copy(d, m)
    w = dst / "model.safetensors"
    w.write_bytes(w.read_bytes()[: w.stat().st_size // 2])
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(dst)], None


def _needing_model(path) -> str:
    """A picture that needs the model (a 32 px glyph: polished through the renderer): a model's
    weights are read when a picture needs them (a picture traced alone never loads it)."""
    from tests.cli.bad_input import glyph_like

    glyph_like(32).save(path)
    return str(path)


def in_model_nan_weights(d, m):
    from safetensors.torch import load_file, save_file

    dst = _model_copy(d, m)
    state = load_file(str(dst / "model.safetensors"))
    key = sorted(k for k, v in state.items() if v.is_floating_point())[0]
    state[key] = state[key].clone().fill_(float("nan"))
    save_file(state, str(dst / "model.safetensors"))
    return ["vectorize", _needing_model(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(dst)], None


def in_model_config_wrong_version(d, m):
    dst = _model_copy(d, m)
    cfg = json.loads((dst / "config.json").read_text())
    cfg["format_version"] = 99
    (dst / "config.json").write_text(json.dumps(cfg))
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(dst)], None


def in_model_config_not_json(d, m):
    dst = _model_copy(d, m)
    (dst / "config.json").write_text("{ not json")
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(dst)], None


def in_model_config_mismatch(d, m):
    dst = _model_copy(d, m)
    cfg = json.loads((dst / "config.json").read_text())
    cfg["latent"] = TINY.latent * 2  # the weights were trained with another latent size
    (dst / "config.json").write_text(json.dumps(cfg))
    return ["vectorize", _needing_model(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(dst)], None


def in_unknown_device(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--device", "tpu:7"], None


def in_models_env_missing(d, m):
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", "fonts", "--env",
            str(d / "no-such-folder")], None


def in_model_config_null(d, m):
    bad = d / "model"
    shutil.copytree(m, bad)
    (bad / "config.json").write_text("null")
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(bad)], None


def in_model_config_out_of_range(d, m):
    bad = d / "model"
    shutil.copytree(m, bad)
    cfg = json.loads((bad / "config.json").read_text())
    cfg["paths"] = 0
    (bad / "config.json").write_text(json.dumps(cfg))
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(bad)], None


def _with_config(d, m, **changes):
    bad = d / "model"
    shutil.copytree(m, bad)
    cfg = json.loads((bad / "config.json").read_text())
    (bad / "config.json").write_text(json.dumps({**cfg, **changes}))
    return ["vectorize", png(d / "a.png"), "-o", str(d / "out.svg"), "--model", str(bad)], None


def in_model_config_huge_sizes(d, m):
    return _with_config(d, m, samples=10**6, max_segments=10**4)  # 6.7 GB before it was bounded


def in_model_config_int_too_large(d, m):
    return _with_config(d, m, latent=2**70)  # torch's randn(): argument 'size' failed to unpack


def in_model_config_sparse(d, m):
    args = _with_config(d, m)
    with open(d / "model" / "config.json", "r+b") as f:
        f.truncate(3 * 2**30)  # 3 GB, sparse: refused from its size, never read
    return args


def in_model_config_fifo(d, m):
    import os

    args = _with_config(d, m)
    (d / "model" / "config.json").unlink()
    os.mkfifo(d / "model" / "config.json")  # nobody writes: a blocking open would wait forever
    return args


def in_model_int8_weights(d, m):
    from safetensors.torch import load_file, save_file

    args = _with_config(d, m)
    weights = d / "model" / "model.safetensors"
    state = load_file(str(weights))
    key = sorted(k for k, v in state.items() if v.is_floating_point())[0]
    save_file({**state, key: state[key].to(torch.int8)}, str(weights))
    return args
