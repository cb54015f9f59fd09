"""`vectorize --engine ray` (issue "Past one machine"): the same SVGs as the local run on a local
Ray cluster, a failed picture named, Ctrl-C, and one line where Ray is not installed."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest
from click.testing import CliRunner
from PIL import Image, ImageDraw, ImageFont

from im2vec_cli.cli import cli
from tests.cli.bad_input import EXE

FONT = "/usr/share/fonts/truetype/dejavu/DejaVuSerif.ttf"


def _glyphs(folder, n=40):
    """``n`` glyphs of DejaVu Serif at 64 px (what is compared here is the two engines' bytes, not
    the model's quality: any face serves)."""
    import string

    if not os.path.exists(FONT):
        pytest.skip("DejaVu fonts are not installed")
    folder.mkdir()
    font = ImageFont.truetype(FONT, 44)
    for i, c in enumerate((string.ascii_letters + string.digits)[:n]):
        img = Image.new("L", (64, 64), 255)
        ImageDraw.Draw(img).text((32, 32), c, font=font, fill=0, anchor="mm")
        img.save(folder / f"g{i:02d}.png")
    return folder


def test_without_ray_the_engine_is_one_line(tmp_path, monkeypatch):
    from tests.helpers import make_tiny_model

    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    (tmp_path / "in").mkdir()
    Image.new("L", (32, 32), 255).save(tmp_path / "in" / "a.png")
    res = CliRunner().invoke(cli, ["vectorize", str(tmp_path / "in"), "-o", str(tmp_path / "out"), "--engine", "ray",
                                   "--model", make_tiny_model(tmp_path / "m")])
    assert res.exit_code == 1, res.output
    assert res.stderr.strip().splitlines() == ["Error: --engine ray needs Ray (Ray Data): pip install 'im2vec[ray]'"]
    res = CliRunner().invoke(cli, ["vectorize", "-", "-o", str(tmp_path / "x.svg"), "--engine", "ray"], input=b"")
    assert res.exit_code == 2 and "--engine ray reads files" in res.stderr


needs_ray = pytest.mark.skipif(subprocess.run([sys.executable, "-c", "import ray.data"], capture_output=True).returncode,
                               reason="Ray is not installed (pip install -e '.[ray]'; make test-slow installs it)")


@pytest.mark.slow  # a local Ray cluster (about 15 s to start and run on 2 cores)
@needs_ray
def test_ray_writes_the_local_runs_svgs_and_names_a_failed_picture(tmp_path):
    """40 held-out glyphs and one truncated PNG: the Ray engine writes the 40 SVGs byte for byte as
    the local run does, names the bad picture on one line, exits 1, prints nothing of Ray's own,
    and leaves no Ray process running."""
    src = _glyphs(tmp_path / "in")
    (src / "broken.png").write_bytes((src / "g00.png").read_bytes()[:60])
    local = subprocess.run(EXE + ["vectorize", str(src), "-o", str(tmp_path / "local")], capture_output=True,
                           text=True, timeout=300)
    ray = subprocess.run(EXE + ["vectorize", str(src), "-o", str(tmp_path / "ray"), "--engine", "ray", "-j", "2"],
                         capture_output=True, text=True, timeout=600)
    for run in (local, ray):
        assert run.returncode == 1, run.stderr
        lines = run.stderr.strip().splitlines()
        assert lines[-1] == "Error: 1 of 41 inputs failed" and len(lines) == 2, run.stderr
        assert lines[0].startswith(f"Error: {src / 'broken.png'}: not a readable image"), run.stderr
    names = sorted(p.name for p in (tmp_path / "local").iterdir())
    assert len(names) == 40 and names == sorted(p.name for p in (tmp_path / "ray").iterdir())
    for name in names:
        assert (tmp_path / "ray" / name).read_bytes() == (tmp_path / "local" / name).read_bytes(), name
    time.sleep(2)
    assert subprocess.run(["pgrep", "-f", "ray/core/src/ray/raylet"], capture_output=True).stdout == b""


@pytest.mark.slow
@needs_ray
def test_ctrl_c_on_ray_keeps_only_whole_svgs_and_ends_the_cluster(tmp_path):
    src = _glyphs(tmp_path / "in", 62)
    for i in range(62, 400):  # enough work to be interrupted
        (src / f"h{i}.png").write_bytes((src / f"g{i % 62:02d}.png").read_bytes())
    out = tmp_path / "out"
    # SIGINT at its default in the child: a shell's background job (a CI script run as `cmd &`) starts
    # with it ignored, and Python keeps ignoring it (the Ctrl-C then did nothing: exit 0, all written)
    p = subprocess.Popen(EXE + ["vectorize", str(src), "-o", str(out), "--engine", "ray", "-j", "2"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.time() + 300
    while time.time() < deadline and not (out.exists() and any(out.glob("*.svg"))):
        time.sleep(0.2)
    p.send_signal(signal.SIGINT)
    err = p.communicate(timeout=120)[1]
    assert p.returncode == 130 and err.strip().endswith("Interrupted.") and "Traceback" not in err, err
    written = list(out.iterdir())
    assert written and len(written) < 400 and all(not f.name.startswith(".") for f in written)
    assert all(f.read_text().rstrip().endswith("</svg>") for f in written)
    time.sleep(3)
    assert subprocess.run(["pgrep", "-f", "ray/core/src/ray/raylet"], capture_output=True).stdout == b""


def test_the_vectorizer_class_is_the_local_run_without_ray(tmp_path):
    """`Vectorizer` (what Ray users pass to `map_batches`) called on a batch as Ray Data gives it:
    bytes and paths, or paths alone; each SVG is `api.vectorize`'s, each failure one line naming
    its picture. No Ray needed to call it."""
    import numpy as np

    from im2vec_cli import api
    from im2vec_cli.rayengine import Vectorizer
    from tests.helpers import make_tiny_model, png

    model = make_tiny_model(tmp_path / "m")
    a, b = png(tmp_path / "a.png", 40, 24), png(tmp_path / "b.png", 30, 30)
    (tmp_path / "bad.png").write_bytes(b"not a picture")
    paths = np.array([a, str(tmp_path / "bad.png"), b], dtype=object)
    actor = Vectorizer(model=model)
    for batch in ({"path": paths, "bytes": np.array([open(p, "rb").read() for p in paths], dtype=object)},
                  {"path": paths}):
        out = actor(batch)
        assert out["path"] == list(paths) and out["error"][0] == out["error"][2] == ""
        assert out["error"][1].startswith(f"{tmp_path / 'bad.png'}: not a readable image") and out["svg"][1] == ""
        m = api.load_model(model)
        assert out["svg"][0] == api.vectorize(a, m).to_svg() and out["svg"][2] == api.vectorize(b, m).to_svg()
