"""``vectorize``'s two ways (issue 70): a picture that is not polished is traced without torch or
the model, and gets what refinement's own run gives it; the model loads where a picture needs it;
folders are planned by their cost."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image, ImageDraw

from im2vec_cli import api, parallel
from im2vec_cli.errors import VectorizeError
from im2vec_cli.files import to_tensor
from im2vec_cli.options import VectorizeOptions

ROOT = Path(__file__).resolve().parents[1]


def logo(path: Path, side: int = 200) -> Path:
    """A smooth two-colour logo of ``side`` px (anti-aliased: drawn 4x and reduced)."""
    big = Image.new("RGB", (side * 4, side * 4), "white")
    d = ImageDraw.Draw(big)
    d.ellipse((side * 0.4, side * 0.4, side * 3.6, side * 3.6), fill=(200, 30, 40))
    d.rectangle((side * 1.4, side * 1.2, side * 2.6, side * 2.8), fill=(20, 30, 120))
    big.resize((side, side), Image.LANCZOS).save(path)
    return path


def _imports_after(args: list[str]) -> set[str]:
    """The top-level modules loaded by ``im2vec ARGS`` in a fresh process."""
    code = ("import sys\nfrom im2vec_cli.cli import main\nsys.argv = ['im2vec', *sys.argv[1:]]\n"
            "try:\n    main()\nexcept SystemExit as e:\n    assert not e.code, e.code\n"
            "print(' '.join(sorted({m.split('.')[0] for m in sys.modules})))")
    out = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=ROOT,
                         env={"PYTHONPATH": str(ROOT / "src"), "PATH": "/usr/bin:/bin"}, check=True)
    return set(out.stdout.split())


def test_a_traced_picture_never_imports_torch(tmp_path):
    """``vectorize`` of a 200 px logo (larger than the polish's 128 px: traced, not polished) in a
    fresh process: the SVG is written and neither torch nor the model was loaded, nor SciPy or
    scikit-image (0.2-0.4 s of imports: the trace's image operations are OpenCV's, trace/ndops.py),
    nor tqdm (no bar shows); ``--help`` too."""
    out = tmp_path / "l.svg"
    mods = _imports_after(["vectorize", str(logo(tmp_path / "l.png")), "-o", str(out)])
    assert out.read_text().startswith("<svg") and "<path" in out.read_text()
    assert "numpy" in mods and "cv2" in mods
    assert not mods & {"torch", "scipy", "skimage", "sklearn", "tqdm"}, mods
    assert "torch" not in _imports_after(["--help"])


def test_a_small_picture_loads_the_model_a_large_one_does_not(tmp_path):
    """The model is loaded at the first picture that needs it (64 px: polished through the
    renderer), never for one that is traced alone (200 px)."""
    calls = []

    def broken():
        calls.append(1)
        raise RuntimeError("the model was asked for")

    model = api.ModelRef(load=broken)
    big = api.vectorize(str(logo(tmp_path / "big.png")), model)
    assert big.shapes and not calls
    with pytest.raises(RuntimeError, match="asked for"):
        api.vectorize(str(logo(tmp_path / "small.png", 64)), model)
    assert calls == [1]
    got = api.vectorize_each([str(tmp_path / "big.png"), str(tmp_path / "small.png")], model)
    assert got[0].shapes and isinstance(got[1], VectorizeError)  # the traced one is not lost with the other


def test_the_traced_way_gives_what_refinement_gives(tmp_path):
    """A picture traced alone (``refine.clean.trace_alone``) gets the SVG that refinement's own batch
    (``refine.refine_batch``, the renderer at hand) gives it: the two ways are one pipeline."""
    from im2vec_cli.options import effort_plan
    from im2vec_cli.refine import refine_batch

    pic = np.asarray(Image.open(logo(tmp_path / "l.png", 160)), dtype=np.float32) / 255
    fonts = api.load_model("fonts", "cpu")
    (ref, info), = refine_batch(fonts, [to_tensor(pic)], effort_plan("fast"))
    assert info["kind"] and info["loss_end"] is None  # not polished: larger than the polish's size
    assert api.vectorize(pic, api.ModelRef(load=lambda: 1 / 0)).to_svg() == ref.to_svg()


def test_folders_are_planned_by_their_cost():
    """Two 512 px pictures on two free cores: two workers (each traces one); two 64 px glyphs (the
    model's start costs more than they do): none; ``-j`` wins; a GPU: one process."""
    o = VectorizeOptions()
    assert parallel.plan_workers(o, [(512, 512)] * 2, 2, most=2)[0] == 2
    assert parallel.plan_workers(o, [(64, 64)] * 2, 2, most=2)[0] == 1
    assert parallel.plan_workers(o, [(64, 64)] * 400, 400, most=2)[0] == 2
    assert parallel.plan_workers(o, [(512, 512)] * 2, 2, most=2, jobs=1)[0] == 1
    assert parallel.plan_workers(o, [(512, 512)] * 9, 9, most=8, gpu=True)[0] == 1
    jobs, chunk, heavy = parallel.plan_workers(o, [(512, 512)] * 100, 100, most=2)
    assert (jobs, chunk, heavy) == (2, 7, False)  # sixteen chunks or more; nothing needs torch
    assert parallel.plan_workers(o, [(64, 64)] * 100, 100, most=2)[2]  # most need the model: torch before the fork
    assert parallel.plan_workers(dataclasses.replace(o, effort="draft"), [(64, 64)] * 2, 2, most=2)[2] is False


def test_a_chunks_large_pictures_go_to_workers_alone_and_come_out_the_same(tmp_path):
    """The pictures the refinement may batch (no longer a side than the polish's) stay one group of
    a chunk; each larger one is a group alone (it is traced alone), so a folder's photos spread over
    the workers; the groups vectorized apart give the SVGs of the chunk vectorized whole."""
    o = VectorizeOptions()
    sides = [(48, 48, 3), (160, 160, 3), (64, 64, 3), (512, 300, 3)]
    assert parallel.batch_groups(o, sides) == [[0, 2], [1], [3]]
    assert parallel.batch_groups(dataclasses.replace(o, parts="model"), sides) == [[0, 1, 2, 3]]  # model batches
    assert parallel.batch_groups(dataclasses.replace(o, effort="draft"), sides) == [[0], [1], [2], [3]]  # no polish
    assert parallel.batch_groups(o, []) == []
    pics = [np.asarray(Image.open(logo(tmp_path / f"{s}.png", s)), dtype=np.float32) / 255 for s in (48, 160, 64)]
    model = api.ModelRef("fonts", "cpu")
    whole = [v.to_svg() for v in api.vectorize_each(pics, model)]
    apart = {}
    for group in parallel.batch_groups(o, [p.shape for p in pics]):
        apart.update(zip(group, (v.to_svg() for v in api.vectorize_each([pics[i] for i in group], model))))
    assert [apart[i] for i in range(len(pics))] == whole


def test_a_broken_model_is_refused_before_any_picture(tmp_path):
    """A model folder whose weights are missing, cut short or stored as int8 is an error when it is
    named, though no picture needs it yet (told from the safetensors header, without torch)."""
    import shutil

    from im2vec_cli.config import REPO_MODELS
    from im2vec_cli.errors import Im2VecError

    src = REPO_MODELS / "fonts"
    for case in ("missing", "truncated"):
        d = tmp_path / case
        shutil.copytree(src, d)
        w = d / "model.safetensors"
        if case == "missing":
            w.unlink()
        else:
            w.write_bytes(w.read_bytes()[: w.stat().st_size // 2])
        with pytest.raises(Im2VecError, match="missing|truncated"):
            api.ModelRef(str(d))
    with pytest.raises(Im2VecError, match="unknown device"):
        api.ModelRef("fonts", "tpu:7")
