"""Issue "Safety" (items 3-6): no work overwritten without a flag, training on tiny folders,
and the surprises of the adversarial pass, each one line or the right result."""

import os
import subprocess
import sys

import pytest
from click.testing import CliRunner

from im2vec_cli.cli import cli
from im2vec_cli.errors import DataError, Im2VecError, ModelError
from tests.helpers import make_tiny_model, png

EXE = [sys.executable, "-m", "im2vec_cli"]
TINY_TRAIN = '{"model": {"image_size": 32, "latent": 8, "paths": 2}, "train": {"batch": 2, "steps": 2, "workers": 1}}'


def one_error_line(r):
    """Exit 1 or 2 with exactly one ``Error:`` line and no traceback (click's usage lines allowed)."""
    err = r.stderr if hasattr(r, "stderr") and isinstance(r.stderr, str) else r.output
    lines = [x for x in err.splitlines() if x.startswith("Error:")]
    return r.returncode if hasattr(r, "returncode") else r.exit_code, lines, "Traceback" not in err


def _images(folder, n):
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        png(folder / f"{i}.png", 32, 32 - i % 3)
    return folder


# --- no work overwritten without a flag ---------------------------------------------------

def test_a_run_folder_is_continued_or_started_over_only_when_asked(tmp_path):
    from im2vec_cli.checkpoint import prepare_run_dir

    run = tmp_path / "run"
    prepare_run_dir(run, resume=False, overwrite=False)  # a fresh folder is made
    assert run.is_dir()
    (run / "checkpoint.pt").write_bytes(b"old")
    (run / "model").mkdir()
    (run / "preview_0000001.png").write_bytes(b"p")
    (run / "notes.txt").write_text("mine")
    with pytest.raises(Im2VecError, match="holds a training run.*--resume.*--overwrite"):
        prepare_run_dir(run, resume=False, overwrite=False)
    assert (run / "checkpoint.pt").read_bytes() == b"old"
    with pytest.raises(Im2VecError, match="give one of them"):
        prepare_run_dir(run, resume=True, overwrite=True)
    prepare_run_dir(run, resume=True, overwrite=False)  # continuing keeps everything
    assert (run / "checkpoint.pt").exists()
    prepare_run_dir(run, resume=False, overwrite=True)  # starting over removes the run's files only
    assert sorted(p.name for p in run.iterdir()) == ["notes.txt"]
    with pytest.raises(Im2VecError, match="no checkpoint.pt to resume from"):
        prepare_run_dir(tmp_path / "new", resume=True, overwrite=False)
    with pytest.raises(Im2VecError, match="inside the training images' folder"):
        prepare_run_dir(tmp_path / "data" / "run", resume=False, overwrite=False, data_dir=tmp_path / "data")
    (tmp_path / "file").write_text("x")
    with pytest.raises(Im2VecError, match="not a folder"):
        prepare_run_dir(tmp_path / "file", resume=False, overwrite=False)


@pytest.mark.slow  # trains tiny models in real processes (about 20 s)
def test_train_onto_a_finished_run_is_refused_then_overwrite_starts_over(tmp_path):
    data = _images(tmp_path / "data", 3)
    (tmp_path / "c.json").write_text(TINY_TRAIN)
    base = EXE + ["train", str(data), "--config", str(tmp_path / "c.json"), "--out", str(tmp_path / "run"),
                  "--device", "cpu"]
    assert subprocess.run(base, capture_output=True).returncode == 0
    before = (tmp_path / "run" / "checkpoint.pt").read_bytes()
    r = subprocess.run(base, capture_output=True, text=True)
    code, lines, clean = one_error_line(r)
    assert code == 1 and len(lines) == 1 and clean and "--resume continues it" in lines[0]
    assert (tmp_path / "run" / "checkpoint.pt").read_bytes() == before  # untouched
    r = subprocess.run(base + ["--overwrite"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "run" / "model" / "config.json").is_file()


@pytest.fixture
def run_dir(tmp_path):
    from im2vec_cli.checkpoint import save_checkpoint
    from im2vec_cli.model.vae import Im2Vec
    from tests.helpers import TINY

    run = tmp_path / "run"
    run.mkdir()
    save_checkpoint(run / "checkpoint.pt", {"model": Im2Vec(TINY).state_dict(), "model_config": TINY.to_dict(),
                                            "step": 5})
    return run


def test_export_replaces_a_folder_whole_only_with_overwrite(tmp_path, run_dir):
    from im2vec_cli.model.pretrained import export_checkpoint

    out = tmp_path / "m"
    out.mkdir()
    (out / "README.md").write_text("the old card")
    (out / "segments.json").write_text("{}")
    with pytest.raises(ModelError, match="holds files; --overwrite replaces the folder whole"):
        export_checkpoint(run_dir, out)
    assert (out / "README.md").read_text() == "the old card"
    folder, step = export_checkpoint(run_dir, out, overwrite=True)
    assert step == 5 and sorted(p.name for p in folder.iterdir()) == ["config.json", "model.safetensors"]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp folder left
    for bad in (run_dir, tmp_path):  # the run itself, or a folder holding it: never replaced
        with pytest.raises(ModelError, match="the folder this reads"):
            export_checkpoint(run_dir, bad, overwrite=True)
    assert (run_dir / "checkpoint.pt").is_file()
    r = CliRunner().invoke(cli, ["export", str(run_dir), "-o", str(out)])
    assert r.exit_code == 1 and "--overwrite" in r.output


def test_replace_folder_keeps_the_old_folder_when_writing_fails(tmp_path):
    from im2vec_cli.files import replace_folder

    out = tmp_path / "m"
    out.mkdir()
    (out / "a").write_text("old")

    def broken(tmp):
        (tmp / "a").write_text("new")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        replace_folder(out, broken)
    assert (out / "a").read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["m"]
    (tmp_path / "f").write_text("x")
    with pytest.raises(OSError, match="not a folder"):
        replace_folder(tmp_path / "f", lambda tmp: None)


def test_fit_prior_and_train_aux_never_write_into_a_model_unasked(tmp_path):
    model = make_tiny_model(tmp_path / "model")
    data = _images(tmp_path / "data", 6)
    before = sorted(p.name for p in (tmp_path / "model").iterdir())
    r = CliRunner().invoke(cli, ["fit-prior", str(data), "--model", model, "--components", "1"])
    assert r.exit_code == 2 and "Missing option '-o'" in r.output  # no -o: nothing is written anywhere
    for cmd in (["fit-prior", str(data), "--components", "1"], ["train-aux", str(data), "--steps", "1"]):
        r = CliRunner().invoke(cli, cmd + ["--model", model, "-o", model])
        assert r.exit_code == 1 and "is the model's own folder; --overwrite" in r.output, r.output
    assert sorted(p.name for p in (tmp_path / "model").iterdir()) == before
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "x").write_text("mine")
    r = CliRunner().invoke(cli, ["fit-prior", str(data), "--model", model, "--components", "1",
                                 "-o", str(tmp_path / "other")])
    assert r.exit_code == 1 and "holds files" in r.output and (tmp_path / "other" / "x").exists()
    r = CliRunner().invoke(cli, ["fit-prior", str(data), "--model", model, "--components", "1",
                                 "-o", model, "--overwrite"])
    assert r.exit_code == 0, r.output
    assert {"latent_prior.json", "latent_prior.safetensors"} <= {p.name for p in (tmp_path / "model").iterdir()}


def test_data_svg_refuses_names_that_collide(tmp_path):
    from im2vec_cli.data.svgset import build_svg_set

    src = tmp_path / "src"
    (src / "a").mkdir(parents=True)
    square = '<svg xmlns="http://www.w3.org/2000/svg" width="8" height="8"><rect width="4" height="4"/></svg>'
    (src / "a" / "b.svg").write_text(square)
    (src / "a__b.svg").write_text(square)
    with pytest.raises(DataError, match=r"a/b\.svg and .*a__b\.svg: both would be written as a__b\.svg"):
        build_svg_set(tmp_path / "out", src, size=16)
    assert not (tmp_path / "out").exists()  # checked before anything is written


# --- training on tiny folders -------------------------------------------------------------

@pytest.mark.slow  # trains tiny models in real processes (about 20 s)
def test_training_on_one_image_is_one_line_and_on_two_needs_no_prior(tmp_path):
    (tmp_path / "c.json").write_text(TINY_TRAIN)
    for n in (0, 1):
        data = _images(tmp_path / f"d{n}", n)
        if n == 0:
            (data / "junk.png").write_bytes(b"not a png")
        r = subprocess.run(EXE + ["train", str(data), "--config", str(tmp_path / "c.json"), "--out",
                                  str(tmp_path / f"r{n}"), "--device", "cpu"], capture_output=True, text=True)
        code, lines, clean = one_error_line(r)
        assert code == 1 and len(lines) == 1 and clean, r.stderr
        assert ("at least 2" in lines[0] and "1 readable image" in lines[0]) if n else "could be read" in lines[0]
    data = _images(tmp_path / "d2", 2)
    r = subprocess.run(EXE + ["train", str(data), "--config", str(tmp_path / "c.json"), "--out",
                              str(tmp_path / "r2"), "--device", "cpu"], capture_output=True, text=True)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    assert "no latent prior: 1 training image" in r.stderr
    assert (tmp_path / "r2" / "model" / "model.safetensors").is_file()
    assert not (tmp_path / "r2" / "model" / "latent_prior.json").exists()


# --- the surprises -----------------------------------------------------------------------

def test_a_folder_named_like_a_model_does_not_shadow_it(tmp_path, monkeypatch):
    from im2vec_cli.config import REPO_MODELS, resolve_model

    monkeypatch.chdir(tmp_path)
    (tmp_path / "fonts").mkdir()
    assert resolve_model("fonts") == REPO_MODELS / "fonts"  # a bare name: the shipped model
    assert resolve_model("./fonts") == tmp_path / "fonts" or resolve_model("./fonts").resolve() == tmp_path / "fonts"
    (tmp_path / "fonts" / "config.json").write_text("{}")
    assert resolve_model("fonts") == tmp_path / "fonts" or resolve_model("fonts").resolve() == tmp_path / "fonts"
    (tmp_path / "mine").mkdir()
    with pytest.raises(Im2VecError, match="config.json"):
        from im2vec_cli.model.pretrained import from_pretrained

        from_pretrained("mine")


def test_stdin_mixed_with_files_and_sets_on_stdout_are_usage_errors(tmp_path):
    g = png(tmp_path / "g.png", 32, 32)
    r = CliRunner().invoke(cli, ["vectorize", "-", g, "-o", str(tmp_path / "o")])
    assert r.exit_code == 2 and "- (stdin) is one input on its own" in r.output
    assert not (tmp_path / "o").exists()
    r = CliRunner().invoke(cli, ["sample", "--n", "2", "-o", "-"])
    assert r.exit_code == 2 and "stdout takes one SVG" in r.output
    r = CliRunner().invoke(cli, ["interpolate", g, g, "-o", "-"])
    assert r.exit_code == 2 and "stdout takes one SVG" in r.output
    assert not os.path.exists("-")


def test_sample_of_one_to_stdout_is_an_svg(tmp_path):
    r = subprocess.run(EXE + ["sample", "--n", "1", "-o", "-", "--parts", "model"], capture_output=True, text=True,
                       cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("<svg") and r.stdout.rstrip().endswith("</svg>") and not os.listdir(tmp_path)


def test_what_a_folder_holds_that_is_not_a_file_is_named(tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    png(folder / "g.png", 32, 32)
    os.symlink(tmp_path / "nothing.png", folder / "broken.png")
    os.mkfifo(folder / "pipe.png")
    r = subprocess.run(EXE + ["vectorize", str(folder), "-o", str(tmp_path / "out"), "--no-refine"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "skipped " + str(folder / "broken.png") + ": a broken link" in r.stderr
    assert "skipped " + str(folder / "pipe.png") + ": not a regular file" in r.stderr
    assert sorted(os.listdir(tmp_path / "out")) == ["g.svg"]


def test_a_newline_in_a_file_name_stays_one_error_line(tmp_path):
    r = subprocess.run(EXE + ["vectorize", str(tmp_path / "a\nb.png"), "-o", str(tmp_path / "x.svg")],
                       capture_output=True, text=True)
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and "a\\nb.png" in r.stderr, r.stderr


@pytest.mark.parametrize("args, warned", [
    (["--no-refine", "--tolerance", "2", "--colors", "3", "--effort", "best"], ["--tolerance", "--colors", "--effort"]),
    (["--parts", "model", "--tolerance", "2"], ["--tolerance"]),
    (["--quality", "0.01"], ["--quality"]),
    (["--tolerance", "2", "--colors", "3"], []),
])
def test_options_that_do_nothing_in_a_mode_are_warned(tmp_path, args, warned):
    g = png(tmp_path / "g.png", 32, 32)
    r = CliRunner().invoke(cli, ["vectorize", g, "-o", str(tmp_path / "g.svg"), *args])
    assert r.exit_code == 0, r.output
    said = sorted(x.split()[1] for x in r.output.splitlines() if x.startswith("Warning:") and "does nothing" in x)
    assert said == sorted(warned)


def test_eval_names_the_images_it_skips(tmp_path):
    model = make_tiny_model(tmp_path / "model")
    data = _images(tmp_path / "data", 2)
    (data / "bad.png").write_bytes(b"not a png")
    out = tmp_path / "res.json"
    r = CliRunner().invoke(cli, ["eval", "--data", str(data), "--model", model, "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert "Warning: skipped " in r.output and "bad.png" in r.output
    assert '"images_skipped": 1' in out.read_text()


# --- an SVG reader and a render that always end ------------------------------------------

def _svg(body, size=100):
    return f'<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{size}">{body}</svg>'


@pytest.mark.parametrize("body, word", [
    ('<defs><clipPath id="c"><rect width="20" height="20"/></clipPath></defs>'
     '<rect width="50" height="50" clip-path="url(#c)"/>', "<rect>: clip-path is not supported"),
    ('<defs><clipPath id="c"><rect width="20" height="20"/></clipPath></defs>'
     '<g clip-path="url(#c)"><rect width="50" height="50"/></g>', "<g>: clip-path"),
    ('<defs><mask id="m"><rect width="20" height="20" fill="white"/></mask></defs>'
     '<rect width="50" height="50" style="fill:red; mask: url(#m)"/>', "<rect>: mask is not supported"),
    ('<style>.x { marker-end: url(#m) }</style><path class="x" d="M10 10 L90 90" stroke="black"/>',
     "<style>: marker-end"),
    ('<path d="M10 10 L90 90" stroke="black" marker-start="url(#m)"/>', "marker-start"),
    ('<rect width="50" height="50" filter="url(#f)"/>', "filter is not supported"),
])
def test_clips_masks_markers_and_filters_are_refused_by_name(body, word):
    from im2vec_cli.errors import InputError
    from im2vec_cli.vector import from_svg

    with pytest.raises(InputError, match=word):
        from_svg(_svg(body))


def test_hidden_shapes_are_not_drawn_and_visibility_is_inherited():
    from im2vec_cli.vector import from_svg

    im = from_svg(_svg('<rect width="50" height="50" visibility="hidden"/><rect x="60" y="60" width="20" height="20"/>'
                       '<g visibility="hidden"><rect width="9" height="9"/>'
                       '<rect x="30" width="5" height="5" visibility="visible"/></g>'
                       '<rect width="5" height="5" clip-path="none"/>'))
    boxes = sorted((c.min(0).tolist(), c.max(0).tolist()) for s in im.shapes for c in s.contours)
    assert boxes == [([0.0, 0.0], [5.0, 5.0]), ([30.0, 0.0], [35.0, 5.0]), ([60.0, 60.0], [80.0, 80.0])]


def test_dashes_are_bounded_before_they_are_made():
    import time

    from im2vec_cli.errors import InputError
    from im2vec_cli.vector import from_svg

    line = '<line x1="0" y1="50" x2="100" y2="50" stroke="black" stroke-width="2" stroke-dasharray="{}"/>'
    start = time.perf_counter()
    with pytest.raises(InputError, match="stroke-dasharray makes about 50,000 dashes"):
        from_svg(_svg(line.format("0.001")))
    assert time.perf_counter() - start < 5  # refused from the arithmetic, not after skia made them
    solid = from_svg(_svg(line.format("none")))
    for same in ("0 0", "-1 2", "0"):  # SVG: a zero sum or a negative value draws the line solid
        got = from_svg(_svg(line.format(same)))
        assert [c.tolist() for s in got.shapes for c in s.contours] == \
            [c.tolist() for s in solid.shapes for c in s.contours]
    dashed = from_svg(_svg(line.format("5 5")))
    assert sum(len(s.contours) for s in dashed.shapes) == 10


def test_banded_point_winding_is_the_brute_force_answer():
    import torch

    from im2vec_cli.raster.winding import _probes, point_winding, point_winding_banded

    g = torch.Generator().manual_seed(0)
    for edges, spread in ((40, 100.0), (600, 30.0)):
        v = torch.rand(2, edges, 2, generator=g) * spread
        v[0, ::7, 1] = v[0, 1::7, 1]  # some horizontal edges, and points on their lines
        a, b = v, torch.roll(v, -1, 1)
        pts = torch.cat([torch.rand(2, 300, 2, generator=g) * spread, _probes(a, b), a], 1)
        assert torch.equal(point_winding_banded(pts, a, b), point_winding(pts, a, b))


def test_render_draws_many_shapes_and_long_contours_as_cairo_does():
    import numpy as np

    from im2vec_cli.vector import from_svg, rasterize_svg, render_vector

    rects = "".join(f'<rect x="{(i % 40) * 5}" y="{(i // 40) * 5}" width="2" height="2" '
                    f'fill="#{(i * 37) % 256:02x}3080"/>' for i in range(1600))
    wave = "M 0 150 " + " ".join(f"L {x} {150 + 40 * np.sin(x / 3):.2f}" for x in range(1, 200)) + " L 200 200 L 0 200 Z"
    svg = _svg(rects + f'<path d="{wave}" fill="#202020"/>', 200)
    got = render_vector(from_svg(svg)).permute(1, 2, 0).numpy()
    ref = rasterize_svg(svg, 200, 200)
    assert np.abs(got - ref).mean() < 0.02 and np.quantile(np.abs(got - ref), 0.99) < 0.25  # edges' antialiasing
    assert (got[3, :, :] == 1).all()  # between the squares: white, not tinted by 1,600 shapes' far coverage
    assert np.allclose(got[198, 5], 32 / 255)


def test_render_refuses_what_it_cannot_bound_in_one_line(tmp_path):
    import random

    rng = random.Random(0)
    pts = " ".join(f"{rng.uniform(0, 1000):.1f},{rng.uniform(0, 1000):.1f}" for _ in range(5000))
    (tmp_path / "star.svg").write_text(_svg(f'<polygon points="{pts}"/>', 1000))
    r = subprocess.run(EXE + ["render", str(tmp_path / "star.svg"), "-o", str(tmp_path / "star.png")],
                       capture_output=True, text=True, timeout=120)
    code, lines, clean = one_error_line(r)
    assert code == 1 and len(lines) == 1 and clean and "too complex to render" in lines[0], r.stderr
    assert not (tmp_path / "star.png").exists()
