import json
import subprocess
import sys
import zlib
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from im2vec_cli.cli import cli
from im2vec_cli.cli.generate import MORPH_FRAMES
from im2vec_cli.vector import rasterize_svg
from tests.helpers import check_svg, make_tiny_model, png, run


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory):
    return make_tiny_model(tmp_path_factory.mktemp("m") / "tiny")


def test_help_and_version():
    assert run(["--help"]).exit_code == 0
    for cmd in ("vectorize", "encode", "sample", "interpolate", "train", "render"):
        res = run([cmd, "--help"])
        assert res.exit_code == 0 and "Exit codes" in res.output
    assert "0.1.0" in run(["--version"]).output


def test_vectorize_file_keeps_input_frame(tmp_path, model_dir):
    src = png(tmp_path / "a.png", 40, 24)
    res = run(["vectorize", src, "-o", str(tmp_path / "a.svg"), "--model", model_dir])
    assert res.exit_code == 0, res.output
    check_svg((tmp_path / "a.svg").read_text(), 40, 24)


@pytest.mark.parametrize("mode", ["L", "RGBA", "P", "I;16"])
def test_vectorize_image_modes(tmp_path, model_dir, mode):
    src = png(tmp_path / "a.png", 30, 30, mode if mode != "I;16" else "L")
    if mode == "I;16":
        Image.open(src).convert("I;16").save(src)
    res = run(["vectorize", src, "-o", "-", "--model", model_dir])
    assert res.exit_code == 0, res.output
    check_svg(res.stdout, 30, 30)


def test_vectorize_folder_and_batch_with_bad_files(tmp_path, model_dir):
    d = tmp_path / "in"
    (d / "sub").mkdir(parents=True)
    png(d / "a.png")
    png(d / "sub" / "b.png")
    (d / "c.png").write_bytes(b"not an image")
    res = CliRunner().invoke(cli, ["vectorize", str(d), "-o", str(tmp_path / "out"), "--model", model_dir])
    assert res.exit_code == 1
    assert (tmp_path / "out" / "a.svg").is_file() and (tmp_path / "out" / "sub" / "b.svg").is_file()
    assert not (tmp_path / "out" / "c.svg").exists()
    assert "c.png" in res.output and "1 of 3 inputs failed" in res.output


def _bomb(path):
    # a valid PNG header that claims 30000 x 30000 pixels
    def chunk(kind, data):
        return len(data).to_bytes(4, "big") + kind + data + zlib.crc32(kind + data).to_bytes(4, "big")

    ihdr = (30000).to_bytes(4, "big") * 2 + bytes([8, 0, 0, 0, 0])
    raw = zlib.compress(b"\x00" * 30001 * 10)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", raw) + chunk(b"IEND", b""))


BAD = {
    "missing": lambda p: None,
    "text": lambda p: p.write_text("hello"),
    "zero": lambda p: p.write_bytes(b""),
    "truncated": lambda p: p.write_bytes(Path(png(p)).read_bytes()[:60]),
    "bomb": _bomb,
}


@pytest.mark.parametrize("kind", list(BAD))
def test_bad_input_is_one_line_error(tmp_path, model_dir, kind):
    src = tmp_path / "x.png"
    BAD[kind](src)
    out = tmp_path / "x.svg"
    res = CliRunner().invoke(cli, ["vectorize", str(src), "-o", str(out), "--model", model_dir])
    assert res.exit_code == 1
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: ") and "Traceback" not in res.output
    assert not out.exists() and not list(tmp_path.glob(".x.svg*"))


def test_bad_model_and_output(tmp_path, model_dir):
    src = png(tmp_path / "a.png")
    res = CliRunner().invoke(cli, ["vectorize", src, "--model", "no-such-model"])
    assert res.exit_code == 1 and res.output.startswith("Error: unknown model")
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "config.json").write_text(Path(model_dir, "config.json").read_text())
    res = CliRunner().invoke(cli, ["vectorize", src, "--model", str(broken)])
    assert res.exit_code == 1 and "missing" in res.output
    res = CliRunner().invoke(cli, ["vectorize", src, "--model", model_dir, "-o", str(tmp_path / "nodir" / "x.svg")])
    assert res.exit_code == 1 and res.output.startswith("Error:") and len(res.output.strip().splitlines()) == 1
    res = CliRunner().invoke(cli, ["vectorize", src, "--model", model_dir, "--segments", "zero"])
    assert res.exit_code == 2


def test_encode_jsonl_and_npy(tmp_path, model_dir):
    a, b = png(tmp_path / "a.png"), png(tmp_path / "b.png", 20, 20)
    res = run(["encode", a, b, "--model", model_dir])
    rows = [json.loads(x) for x in res.stdout.splitlines()]
    assert [r["file"] for r in rows] == [a, b] and len(rows[0]["latent"]) == 16
    res = run(["encode", a, "--format", "npy", "-o", str(tmp_path / "z"), "--model", model_dir])
    assert res.exit_code == 0
    assert np.load(tmp_path / "z" / "a.npy").shape == (16,)


def test_sample_and_interpolate(tmp_path, model_dir):
    res = run(["sample", "--n", "3", "-o", str(tmp_path / "s"), "--model", model_dir, "--seed", "1"])
    assert res.exit_code == 0
    assert len(list((tmp_path / "s").glob("*.svg"))) == 3 and (tmp_path / "s" / "contact.png").is_file()
    a, b = png(tmp_path / "a.png"), png(tmp_path / "b.png", 20, 30)
    run(["encode", b, "--format", "npy", "-o", str(tmp_path / "z"), "--model", model_dir])
    res = run(["interpolate", a, str(tmp_path / "z" / "b.npy"), "--steps", "4", "-o", str(tmp_path / "i"),
               "--model", model_dir, "--animate"])
    assert res.exit_code == 0, res.output
    frames = sorted((tmp_path / "i").glob("frame_*.svg"))
    assert len(frames) == 6
    for f in frames:
        check_svg(f.read_text(), 32, 32)
    morph = (tmp_path / "i" / "morph.svg").read_text()
    root = ElementTree.fromstring(morph)
    anims = [g.find("{http://www.w3.org/2000/svg}animate") for g in root.iter("{http://www.w3.org/2000/svg}g")]
    shown = np.array([a.get("values").split(";") for a in anims]) == "inline"  # (frames, slots)
    assert shown.shape == (MORPH_FRAMES, 2 * MORPH_FRAMES - 2)  # there and back
    assert (shown.sum(0) == 1).all() and (shown.sum(1) >= 1).all()  # one frame at a time, every frame shown
    still = rasterize_svg(morph, 32, 32)  # without SMIL: the first frame, which is frame_0
    assert np.abs(still - rasterize_svg(frames[0].read_text(), 32, 32)).max() < 1e-6
    np.save(tmp_path / "nan.npy", np.full(16, np.nan, np.float32))
    res = CliRunner().invoke(cli, ["interpolate", a, str(tmp_path / "nan.npy"), "-o", str(tmp_path / "j"),
                                   "--model", model_dir])
    assert res.exit_code == 1 and "NaN" in res.output


def test_subprocess_pipeline(tmp_path, model_dir):
    src = png(tmp_path / "g.png", 32, 32)
    exe = [sys.executable, "-m", "im2vec_cli"]
    out = tmp_path / "g.svg"
    r = subprocess.run(exe + ["vectorize", src, "-o", str(out), "--model", model_dir], capture_output=True)
    assert r.returncode == 0, r.stderr
    check_svg(out.read_text(), 32, 32)
    r = subprocess.run(exe + ["vectorize", "-", "--model", model_dir], input=Path(src).read_bytes(),
                       capture_output=True)
    assert r.returncode == 0 and r.stderr == b""
    check_svg(r.stdout.decode(), 32, 32)
    r = subprocess.run(exe + ["vectorize", "-", "--model", model_dir], input=b"junk", capture_output=True)
    assert r.returncode == 1 and r.stdout == b"" and r.stderr.decode().count("\n") == 1


def test_vectorize_refine_flag(tmp_path, model_dir):
    from im2vec_cli.raster import set_compile

    src = png(tmp_path / "a.png", 40, 24)
    try:
        res = run(["vectorize", src, "-o", str(tmp_path / "a.svg"), "--model", model_dir, "--refine"])
    finally:
        set_compile(None)
    assert res.exit_code == 0, res.output
    check_svg((tmp_path / "a.svg").read_text(), 40, 24)
    try:
        res = run(["vectorize", src, "-o", str(tmp_path / "b.svg"), "--model", model_dir, "--effort", "best"])
    finally:
        set_compile(None)
    assert res.exit_code == 0, res.output
    check_svg((tmp_path / "b.svg").read_text(), 40, 24)
    res = run(["vectorize", src, "-o", str(tmp_path / "c.svg"), "--model", model_dir, "--effort", "slow"])
    assert res.exit_code == 2 and not (tmp_path / "c.svg").exists()


def test_choice_lists_are_written_once_and_keep_torch_out_of_help():
    """The CLI's choices are options.py's lists (one definition), the pipelines use the same
    lists, and importing them with the CLI starts no torch (a real process: `--help`)."""
    from im2vec_cli import config, infer, options, refine, trace
    from im2vec_cli.cli import evaluation, generate, sample, training, vectorize

    def choices(command, name):
        return tuple(next(p for p in command.params if p.name == name).type.choices)

    assert tuple(options.EFFORT_SETTINGS) == options.EFFORTS == choices(vectorize, "effort")
    assert choices(vectorize, "preset") == options.PRESETS and trace.KINDS == options.PRESETS[1:]
    assert refine.PARTS is options.PARTS and choices(vectorize, "parts") == options.PARTS == choices(sample, "parts")
    assert infer.PRIORS is options.PRIORS and choices(sample, "prior") == options.PRIORS
    assert choices(evaluation.eval_cmd, "prior") == options.PRIORS == choices(generate.sample, "prior")
    assert config.GROUPINGS is options.GROUPINGS and choices(training.train, "grouping") == options.GROUPINGS
    assert choices(training.train, "arch") == options.ARCHS and choices(training.train_features, "fit") == options.FITS
    code = "import sys, im2vec_cli.cli; print('torch' in sys.modules)"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.stdout.strip() == "False", r.stderr


@pytest.mark.parametrize("field, value", [("effort", "slow"), ("parts", "all"), ("tolerance", 0), ("colors", 65),
                                          ("max_paths", 0), ("segments", 0), ("quality", float("nan")),
                                          ("simplify_px", -1), ("colors", True), ("preset", "poster"),
                                          ("speckle", -1), ("speckle", 2.5), ("effort", "sketch")])
def test_vectorize_options_are_checked_where_they_are_made(field, value):
    from im2vec_cli.options import VectorizeOptions

    with pytest.raises(ValueError, match=field):
        VectorizeOptions(**{field: value})
    import dataclasses

    with pytest.raises(ValueError, match=field):
        dataclasses.replace(VectorizeOptions(), **{field: value})


def test_vectorize_verbose_says_what_each_picture_was_read_as(tmp_path, model_dir):
    """-v: one line per picture on stderr, the kind chosen (pixel art here) and its figures."""
    rng = np.random.default_rng(0)
    sprite = rng.integers(0, 256, (5, 3), dtype=np.uint8)[rng.integers(0, 5, (8, 8))]
    Image.fromarray(np.kron(sprite, np.ones((6, 6, 1), np.uint8))).save(tmp_path / "s.png")
    res = CliRunner().invoke(cli, ["vectorize", str(tmp_path / "s.png"), "-o", str(tmp_path / "s.svg"), "-v",
                                   "--model", model_dir])
    assert res.exit_code == 0, res.output
    assert res.stderr.strip().splitlines() == [f"{tmp_path / 's.png'}: pixel (block 6); 5 paths, "
                                               f"{res.stderr.split('paths, ')[1].split(' ')[0]} segments"]


@pytest.mark.parametrize("parts, kind", [("clean", "the model's guess, mended"), ("model", "the model's paths")])
def test_vectorize_verbose_names_the_guess_without_refinement(tmp_path, model_dir, parts, kind):
    """-v with --no-refine: the line says whether the guess was mended (--parts clean) or is the model's own paths."""
    Image.fromarray(np.full((16, 16, 3), 255, np.uint8)).save(tmp_path / "w.png")
    res = CliRunner().invoke(cli, ["vectorize", str(tmp_path / "w.png"), "-o", str(tmp_path / "w.svg"), "-v",
                                   "--no-refine", "--parts", parts, "--model", model_dir])
    assert res.exit_code == 0, res.output
    (line,) = res.stderr.strip().splitlines()
    assert line.startswith(f"{tmp_path / 'w.png'}: {kind}; "), line


def test_an_output_named_for_another_kind_is_refused(tmp_path, model_dir):
    """`vectorize -o out.png` wrote an SVG into a .png, silently; `render -o x.svg` likewise a PNG."""
    src = png(tmp_path / "a.png")
    res = CliRunner().invoke(cli, ["vectorize", src, "-o", str(tmp_path / "out.png"), "--model", model_dir])
    assert res.exit_code == 2 and "this writes SVG; give the output a .svg name" in res.stderr
    assert not (tmp_path / "out.png").exists()
    (tmp_path / "s.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" width="8" height="8"><rect width="4" '
                                    'height="4"/></svg>')
    res = CliRunner().invoke(cli, ["render", str(tmp_path / "s.svg"), "-o", str(tmp_path / "x.svg")])
    assert res.exit_code == 2 and "this writes PNG" in res.stderr


def test_encode_npy_of_one_image_to_a_file_name_writes_that_file(tmp_path, model_dir):
    """`encode --format npy -o z.npy` made a folder named z.npy; for one image it is the file."""
    src = png(tmp_path / "a.png")
    res = CliRunner().invoke(cli, ["encode", src, "--format", "npy", "--no-fit", "-o", str(tmp_path / "z.npy"),
                                   "--model", model_dir])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "z.npy").is_file() and np.load(tmp_path / "z.npy").shape == (16,)
    res = CliRunner().invoke(cli, ["encode", src, str(png(tmp_path / "b.png")), "--format", "npy", "--no-fit", "-o",
                                   str(tmp_path / "zs"), "--model", model_dir])
    assert res.exit_code == 0 and sorted(p.name for p in (tmp_path / "zs").iterdir()) == ["a.npy", "b.npy"]


def test_eval_scores_a_test_split_or_says_it_does_not(tmp_path, model_dir):
    """A dataset with train/ and no test/ is refused (its training images were scored silently);
    a plain folder is scored whole with a warning."""
    (tmp_path / "set" / "train").mkdir(parents=True)
    png(tmp_path / "set" / "train" / "a.png", 32, 32)
    res = CliRunner().invoke(cli, ["eval", "--model", model_dir, "--data", str(tmp_path / "set"), "-o",
                                   str(tmp_path / "e.json")])
    assert res.exit_code == 1 and "has train/ but no test/" in res.stderr and not (tmp_path / "e.json").exists()
    (tmp_path / "plain").mkdir()
    png(tmp_path / "plain" / "a.png", 32, 32)
    res = CliRunner().invoke(cli, ["eval", "--model", model_dir, "--data", str(tmp_path / "plain"), "-o",
                                   str(tmp_path / "e.json")])
    assert res.exit_code == 0, res.output
    assert "has no test/ folder: every image in it is scored" in res.stderr


@pytest.mark.parametrize("command", ["sample", "interpolate", "encode"])
def test_every_command_follows_the_thread_rule(tmp_path, model_dir, monkeypatch, command):
    """`interpolate`, `encode` and `sample` used every thread (27-43 s instead of 3 s with the
    other core busy): like `vectorize`, they take the free cores, one thread when only one is."""
    import im2vec_cli.runtime as runtime

    calls = []
    monkeypatch.setattr(runtime, "free_cores", lambda *a, **k: 1)
    monkeypatch.setattr(runtime, "set_threads", calls.append)
    a, b = png(tmp_path / "a.png", 32, 32), png(tmp_path / "b.png", 32, 32)
    args = {"sample": ["sample", "--n", "3", "-o", str(tmp_path / "s")],
            "interpolate": ["interpolate", a, b, "--steps", "2", "--no-fit", "-o", str(tmp_path / "i")],
            "encode": ["encode", a, b, "--no-fit", "-o", str(tmp_path / "z.jsonl")]}[command]
    res = CliRunner().invoke(cli, args + ["--model", model_dir])
    assert res.exit_code == 0, res.output
    assert calls == [1]
