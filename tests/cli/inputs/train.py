"""Bad configs for `train --config` (builders as in ``vectorize.py``)."""

from __future__ import annotations

from tests.helpers import png


def _config(d, text):
    (d / "c.json").write_text(text)
    (d / "data").mkdir()
    png(d / "data" / "a.png", 32, 32)
    return ["train", str(d / "data"), "--config", str(d / "c.json"), "--out", str(d / "outrun")], None


def in_config_null(d, m):
    return _config(d, "null")


def in_config_list(d, m):
    return _config(d, "[1, 2, 3]")


def in_config_model_not_object(d, m):
    return _config(d, '{"model": [1]}')


def in_config_segments_zero(d, m):
    return _config(d, '{"model": {"segments": 0}}')


def in_config_lr_negative(d, m):
    return _config(d, '{"train": {"lr": -1}}')


def in_config_distill_imagevae(d, m):
    return _config(d, '{"model": {"arch": "imagevae"}, "train": {"distill": 1.0}}')


def in_config_outline_imagevae(d, m):
    return _config(d, '{"model": {"arch": "imagevae"}, "train": {"outline": 0.01}}')
