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


def in_config_binary(d, m):
    """A PNG given as the config (it was `UnicodeDecodeError: 'utf-8' codec can't decode byte 0x89`)."""
    args = _config(d, "")
    (d / "c.json").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)))
    return args


def in_config_sparse(d, m):
    """A sparse 3 GB config file (read whole: 6.4 GB): refused from its size."""
    args = _config(d, "")
    with open(d / "c.json", "r+b") as f:
        f.truncate(3 * 2**30)
    return args


def in_batch_huge(d, m):
    """`--batch` far past any run (6.2 GB on 3 images): refused before the images load."""
    args = _config(d, "{}")
    return args[0] + ["--batch", "1000000"], None
