"""One picture, fast (issue "`im2vec vectorize glyph.png -o glyph.svg` in about two seconds"):
threads by the work, cairo without cairocffi's start-up (pixel for pixel cairosvg's render),
and a default `vectorize` of a two-tone picture that imports neither cairosvg nor SciPy."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from im2vec_cli import runtime
from im2vec_cli.vector import VectorImage, VectorShape, cairo, fill_vector, rasterize_svg, to_svg
from tests.helpers import circle, make_tiny_model, png, polyline_as_cubic, run

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory):
    return make_tiny_model(tmp_path_factory.mktemp("m") / "tiny")


# --- threads ---------------------------------------------------------------------------------------


def test_one_picture_gets_one_thread_and_many_share_the_free_cores():
    assert runtime.intra_op_threads(1, free=8) == 1
    assert runtime.intra_op_threads(0, free=8) == 1
    assert runtime.intra_op_threads(50, free=8) == 8
    assert runtime.intra_op_threads(50, jobs=2, free=8) == 4
    assert runtime.intra_op_threads(50, jobs=4, free=2) == 1  # never fewer than one


def test_free_cores_counts_a_busy_loop(monkeypatch):
    assert 1 <= runtime.free_cores() <= runtime.cpu_cores()
    monkeypatch.setattr(runtime, "cpu_cores", lambda: 2)
    real_open = open

    def fake_loadavg(running):
        def fake(path, *a, **k):
            if path == "/proc/loadavg":
                import io

                return io.StringIO(f"1.00 0.50 0.20 {running}/300 4242\n")
            return real_open(path, *a, **k)

        return fake

    monkeypatch.setattr("builtins.open", fake_loadavg(1))  # this process alone
    assert runtime.free_cores() == 2
    monkeypatch.setattr("builtins.open", fake_loadavg(2))  # and one busy loop
    assert runtime.free_cores() == 1
    monkeypatch.setattr("builtins.open", fake_loadavg(9))  # a loaded machine: still one
    assert runtime.free_cores() == 1


def test_set_threads_leaves_an_explicit_omp_setting(monkeypatch):
    before = torch.get_num_threads()
    try:
        monkeypatch.setenv("OMP_NUM_THREADS", "3")
        runtime.set_threads(1)
        assert torch.get_num_threads() == before
        monkeypatch.delenv("OMP_NUM_THREADS")
        runtime.set_threads(1)
        assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(before)


def test_vectorize_runs_one_picture_on_one_thread_and_a_folder_on_the_free_cores(tmp_path, model_dir, monkeypatch):
    asked = []
    monkeypatch.setattr(runtime, "set_threads", asked.append)
    monkeypatch.setattr(runtime, "free_cores", lambda: 2)
    src = png(tmp_path / "a.png")
    assert run(["vectorize", src, "-o", str(tmp_path / "a.svg"), "--model", model_dir]).exit_code == 0
    folder = tmp_path / "many"
    folder.mkdir()
    for i in range(3):
        png(folder / f"{i}.png")
    assert run(["vectorize", str(folder), "-o", str(tmp_path / "out"), "--model", model_dir]).exit_code == 0
    assert asked == [1, 2]


def _ring(cx, cy, r):
    return circle(cx, cy, r, segments=8).numpy()


# --- cairo without cairocffi ----------------------------------------------------------------------


def _pictures():
    g = np.random.default_rng(3)
    star = polyline_as_cubic([(20 + 15 * np.cos(a) * (1 if k % 2 else 0.4), 18 + 15 * np.sin(a) * (1 if k % 2 else 0.4))
                              for k, a in enumerate(np.linspace(0, 2 * np.pi, 11)[:-1])]).numpy()
    ring = [_ring(30.37, 22.111, 14.2), _ring(30.37, 22.111, 5.5)[::-1].copy()]
    wobbly = _ring(24, 20, 10) + g.normal(0, 1.5, (24, 2))
    return [
        VectorImage(48, 40, [VectorShape(ring, (0.1, 0.2, 0.6), "nonzero")]),
        VectorImage(48, 40, [VectorShape([star, _ring(20, 18, 6)], (0.0, 0.0, 0.0), "evenodd"),
                             VectorShape([wobbly], (0.9, 0.5, 0.123), "nonzero")]),
        VectorImage(48, 40, [VectorShape([_ring(-5, 30, 20)], (1.0, 0.0, 0.0), "nonzero"), VectorShape([], (0, 0, 0))]),
        VectorImage(24, 20, [VectorShape(ring, (0.3, 0.3, 0.3), "evenodd")]),  # drawn at 2x (a viewBox half the size)
        VectorImage(48, 40, []),
    ]


@pytest.mark.parametrize("fallback", [False, True])
def test_fill_vector_draws_what_cairosvg_draws(fallback, monkeypatch):
    """Pixel for pixel the render of the SVG text by cairosvg (the independent reference), at 1x
    and 2x, under both rules, in colour, off the canvas, empty; and through cairosvg itself when
    libcairo cannot be loaded directly."""
    if fallback:
        monkeypatch.setattr(cairo, "_cairo", lambda: None)
    elif cairo._cairo() is None:
        pytest.skip("libcairo is not loadable through ctypes here")
    for vec in _pictures():
        ours = fill_vector(vec, 48, 40)
        ref = rasterize_svg(to_svg(vec, 3), 48, 40)
        assert ours.shape == ref.shape == (40, 48, 3)
        assert np.array_equal(ours, ref)
    assert fill_vector(_pictures()[1], 48, 40).min() < 0.01  # the pictures are not blank


# --- what a default vectorize imports --------------------------------------------------------------


def test_default_vectorize_of_a_glyph_imports_neither_cairo_nor_scipy(tmp_path):
    """Start-up: the default pipeline of a two-tone picture needs no cairo (0.3-0.5 s to import)
    and no SciPy (0.3 s); nor does a colour picture (its palette's k-means is trace/ndops.py's)."""
    code = (
        "import json, sys\n"
        "import im2vec_cli as iv\n"
        f"iv.vectorize({str(ROOT / 'examples' / 'glyph_a.png')!r})\n"
        "glyph = sorted(m for m in ('cairosvg', 'cairocffi', 'scipy', 'sklearn') if m in sys.modules)\n"
        f"iv.vectorize({str(ROOT / 'examples' / 'emoji_grin.png')!r})\n"
        "print(json.dumps([glyph, sorted(m for m in ('scipy', 'skimage', 'sklearn') if m in sys.modules)]))\n"
    )
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    glyph, colour = json.loads(out.stdout.strip().splitlines()[-1])
    assert glyph == []
    assert colour == []


def test_start_up_runs_without_the_collector_and_restores_it(tmp_path, model_dir):
    import gc

    from im2vec_cli.cli.app import starting_up

    assert gc.isenabled()
    with starting_up():
        assert not gc.isenabled()
    assert gc.isenabled()
    gc.disable()  # a caller that had it off keeps it off
    try:
        with starting_up():
            pass
        assert not gc.isenabled()
    finally:
        gc.enable()
    with pytest.raises(RuntimeError), starting_up():  # and an error on the way does not leave it off
        raise RuntimeError
    assert gc.isenabled()
    assert run(["vectorize", png(tmp_path / "a.png"), "-o", str(tmp_path / "a.svg"), "--model", model_dir]).exit_code == 0
    assert gc.isenabled()


def test_lazy_commands_are_the_modules_commands():
    """app.LAZY names every command of the modules ``vectorize`` does not import, with its module:
    a command missing from it would be missing from ``im2vec``; help lists them all."""
    from click.testing import CliRunner

    from im2vec_cli.cli import app, cli

    names = cli.list_commands(None)  # imports every lazy module
    where = {n: cli.commands[n].callback.__module__.rsplit(".", 1)[-1] for n in names}
    lazy = {n: m for n, m in where.items() if m not in ("convert", "generate")}
    assert lazy == app.LAZY
    out = CliRunner().invoke(cli, ["--help"]).output
    assert all(n in out for n in names)


def test_vectorize_does_not_import_the_training_commands():
    code = ("import sys\nimport im2vec_cli.cli\n"
            "print(sorted(m for m in sys.modules if m.startswith('im2vec_cli.cli.')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "im2vec_cli.cli.training" not in out and "im2vec_cli.cli.convert" in out
