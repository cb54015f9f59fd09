"""Batches (issue "Hardening"): a thousand files with bad ones among them, streaming, worker
processes, Ctrl-C in a real process, byte-identical reruns; and `sample` streaming in chunks."""

from __future__ import annotations

import os
import subprocess

import pytest
from click.testing import CliRunner
from PIL import Image

from im2vec_cli.cli import cli
from tests.cli.bad_input import EXE, glyph_like
from tests.helpers import check_svg, png


@pytest.mark.slow  # 1,000 files through worker processes
def test_batch_of_1000_with_5_percent_bad(tmp_path, model_dir, monkeypatch):
    """Every good file is written (refined, in worker processes: the defaults for a folder this
    large), every bad one is listed, exit 1; images are streamed."""
    import im2vec_cli.parallel as parallel
    import im2vec_cli.runtime as runtime

    jobs, real = [], parallel.vectorize_chunks
    monkeypatch.setattr(parallel, "vectorize_chunks", lambda *a, **kw: jobs.append(kw) or real(*a, **kw))
    monkeypatch.setattr(runtime, "free_cores", lambda: os.cpu_count() or 1)  # a quiet machine, whatever runs beside
    d = tmp_path / "in"
    d.mkdir()
    good = glyph_like(32)
    bad = set(range(0, 1000, 20))  # 50 bad files
    for i in range(1000):
        p = d / f"g{i:04d}.png"
        if i in bad:
            p.write_bytes(b"\x89PNG broken" if i % 40 else b"")
        else:
            good.save(p)
    res = CliRunner().invoke(cli, ["vectorize", str(d), "-o", str(tmp_path / "out"), "--model", model_dir])
    assert res.exit_code == 1
    written = sorted(p.stem for p in (tmp_path / "out").glob("*.svg"))
    assert written == [f"g{i:04d}" for i in range(1000) if i not in bad]
    errors = [line for line in res.stderr.splitlines() if line.startswith("Error:")]
    assert len(errors) == 51 and errors[-1] == "Error: 50 of 1000 inputs failed"
    assert {line.split(":")[1].strip().rsplit("/", 1)[-1] for line in errors[:-1]} == {
        f"g{i:04d}.png" for i in bad}
    expected = min(os.cpu_count() or 1, 8)
    assert (jobs[0]["jobs"], jobs[0]["options"].refine, jobs[0]["options"].compile) == (expected, True, False) \
        if expected > 1 else not jobs


@pytest.mark.parametrize("refine", [True, False])
def test_batch_streams_in_chunks(tmp_path, model_dir, monkeypatch, refine):
    """At most one chunk of images is alive at any time: one refinement batch per chunk by
    default, one forward pass per chunk with --no-refine."""
    import im2vec_cli.cli.convert as cli_mod
    import im2vec_cli.infer as infer
    import im2vec_cli.refine as refinement

    d = tmp_path / "in"
    d.mkdir()
    for i in range(70):
        glyph_like(32).save(d / f"g{i:03d}.png")
    sizes = []
    mod, name = (refinement, "refine_batch") if refine else (infer, "vectorize")
    real = getattr(mod, name)
    monkeypatch.setattr(mod, name, lambda model, images, *a, **kw: sizes.append(len(images)) or real(model, images, *a, **kw))
    res = CliRunner().invoke(cli, ["vectorize", str(d), "-o", str(tmp_path / "out"), "--model", model_dir, "-j", "1"]
                             + ([] if refine else ["--no-refine"]))
    assert res.exit_code == 0 and sum(sizes) == 70 and max(sizes) == cli_mod.VECTORIZE_CHUNK
    assert len(list((tmp_path / "out").glob("*.svg"))) == 70


def test_worker_processes_write_what_one_process_writes(tmp_path, model_dir):
    """`-j 2` (chunks refined in two worker processes) writes byte for byte what `-j 1` writes,
    on a folder of several image sizes (several refinement groups)."""
    d = tmp_path / "in"
    d.mkdir()
    for i in range(12):
        glyph_like(30 + i % 4).save(d / f"g{i:02d}.png")
    outs = []
    for jobs in ("1", "2"):
        res = CliRunner().invoke(cli, ["vectorize", str(d), "-o", str(tmp_path / jobs), "--model", model_dir, "-j", jobs])
        assert res.exit_code == 0, res.output
        outs.append({p.name: p.read_text() for p in (tmp_path / jobs).glob("*.svg")})
    assert len(outs[0]) == 12 and outs[0] == outs[1]


@pytest.mark.slow  # a real SIGINT into 1,200 files, twice
@pytest.mark.parametrize("jobs", ["1", "2"])
def test_ctrl_c_in_a_real_process_leaves_only_complete_svgs(tmp_path, model_dir, jobs):
    """A real SIGINT (what Ctrl-C sends) while a folder is being refined, once the first chunk
    is written: exit 130, one line, every SVG on disk complete, no temp file, the rest absent."""
    import signal
    import time

    d = tmp_path / "in"
    d.mkdir()
    n = 1200  # seconds of work after the first chunk, so that a busy machine cannot finish it before the signal
    for i in range(n):
        glyph_like(32 + i % 3).save(d / f"g{i:04d}.png")
    out = tmp_path / "out"
    # SIGINT at its default in the child: a shell's background job (`cmd &`, e.g. a CI script run
    # that way) starts with it ignored, and Python then keeps ignoring it, as a background job should
    proc = subprocess.Popen(EXE + ["vectorize", str(d), "-o", str(out), "--model", model_dir, "--jobs", jobs],
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.time() + 240
    while time.time() < deadline and not list(out.glob("*.svg")) and proc.poll() is None:
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    written = sorted(out.glob("*.svg"))
    assert proc.returncode == 130, (err, f"{len(written)} of {n} written")
    assert "Traceback" not in err and err.strip().splitlines()[-1] == "Interrupted."
    assert 0 < len(written) < n
    for p in written:
        check_svg(p.read_text(), 32 + int(p.stem[1:]) % 3, 32 + int(p.stem[1:]) % 3)
    assert [p.name for p in out.iterdir() if p.suffix != ".svg"] == []


@pytest.mark.slow  # four real processes; in-process runs are checked byte-identical by the batch tests
def test_determinism_byte_identical(tmp_path, model_dir):
    """Same input, model and seed: byte-identical SVGs from separate processes."""
    src = png(tmp_path / "a.png", 37, 29)
    outs = []
    for i in range(2):
        out = tmp_path / f"o{i}.svg"
        r = subprocess.run(EXE + ["vectorize", src, "-o", str(out), "--model", model_dir, "--seed", "3"],
                           capture_output=True)
        assert r.returncode == 0, r.stderr
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]
    samples = []
    for i in range(2):
        r = subprocess.run(EXE + ["sample", "--n", "3", "-o", str(tmp_path / f"s{i}"), "--model", model_dir,
                                  "--seed", "5"], capture_output=True)
        assert r.returncode == 0, r.stderr
        samples.append([p.read_bytes() for p in sorted((tmp_path / f"s{i}").glob("*.svg"))])
    assert samples[0] == samples[1]


@pytest.mark.parametrize("refine", ["--refine", "--no-refine"])
def test_interrupt_keeps_exactly_the_finished_svgs(tmp_path, model_dir, monkeypatch, refine):
    """Ctrl-C after 5 images (of 40; chunks of 32 without refinement): every finished SVG is
    on disk and complete, nothing else is, and the exit code is 130."""
    import im2vec_cli.cli.convert as convert
    import im2vec_cli.vectorizing as api  # vectorize_each's vectorize

    d = tmp_path / "in"
    d.mkdir()
    for i in range(40):
        png(d / f"{i:02d}.png")
    monkeypatch.setattr(convert, "VECTORIZE_CHUNK", 5)
    real, done = api.vectorize, []

    def interrupted(images, *a, **kw):
        if len(done) >= 5:
            raise KeyboardInterrupt
        out = real(images, *a, **kw)
        done.extend(out if isinstance(out, list) else [out])
        return out

    monkeypatch.setattr(api, "vectorize", interrupted)
    res = CliRunner().invoke(cli, ["vectorize", str(d), "-o", str(tmp_path / "out"), refine, "--model", model_dir,
                                   "-j", "1"])
    assert res.exit_code == 130, res.output
    written = sorted((tmp_path / "out").iterdir())
    assert [p.name for p in written] == [f"{i:02d}.svg" for i in range(5)]
    for p in written:
        check_svg(p.read_text(), 40, 24)


def test_sample_streams_and_bounds_the_contact_sheet(tmp_path, model_dir, monkeypatch):
    import im2vec_cli.cli.generate as generate

    monkeypatch.setattr(generate, "DECODE_CHUNK", 7)
    monkeypatch.setattr(generate, "CONTACT_MAX", 10)
    res = CliRunner().invoke(cli, ["sample", "--n", "30", "-o", str(tmp_path / "s"), "--model", model_dir])
    assert res.exit_code == 0, res.output
    assert len(list((tmp_path / "s").glob("sample_*.svg"))) == 30
    with Image.open(tmp_path / "s" / "contact.png") as sheet:
        assert sheet.size == (8 * 96, 2 * 96)  # the first 10 samples: two rows of 8 cells
    whole = CliRunner().invoke(cli, ["sample", "--n", "30", "-o", str(tmp_path / "t"), "--model", model_dir])
    assert whole.exit_code == 0
    for p in (tmp_path / "s").glob("sample_*.svg"):  # chunking changes nothing
        assert p.read_bytes() == (tmp_path / "t" / p.name).read_bytes()


def test_one_pictures_failure_is_its_own(tmp_path, model_dir, monkeypatch):
    """Any exception inside one picture's pipeline (injected: a dependency's error in the
    outline step of the 33 px picture) fails that picture alone: every other SVG is written,
    the bad picture is named in one line, exit 1, no traceback."""
    import im2vec_cli.trace.pipeline as pipeline

    real = pipeline.untangle

    def flaky(vec):
        if vec.width == 33:
            raise RuntimeError("operation did not succeed")
        return real(vec)

    monkeypatch.setattr(pipeline, "untangle", flaky)
    d = tmp_path / "in"
    d.mkdir()
    for i, size in enumerate((32, 33, 32, 34)):
        glyph_like(size).save(d / f"g{i}.png")
    res = CliRunner().invoke(cli, ["vectorize", str(d), "-o", str(tmp_path / "out"), "--model", model_dir])
    assert res.exit_code == 1 and "Traceback" not in res.output
    errors = [x for x in res.stderr.splitlines() if x.startswith("Error:")]
    assert errors[0] == f"Error: {d / 'g1.png'}: could not vectorize: RuntimeError: operation did not succeed"
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["g0.svg", "g2.svg", "g3.svg"]


def test_a_worker_returns_a_failed_picture_in_its_place(model_dir):
    """In worker processes too: a picture that fails (here: too small to hold a shape) comes
    back as a VectorizeError in its place, the others as vector images."""
    import numpy as np

    from im2vec_cli import parallel
    from im2vec_cli.errors import VectorizeError

    good = np.asarray(glyph_like(32).convert("RGB"), np.float32) / 255
    bad = np.zeros((2, 2, 3), np.float32)
    (out,) = parallel.vectorize_chunks([[good, bad, good]], model_dir, jobs=1, threads=1, device="cpu")
    assert [type(v).__name__ for v in out] == ["VectorImage", "VectorizeError", "VectorImage"]
    assert isinstance(out[1], VectorizeError) and str(out[1]) == "could not vectorize: image too small (2x2 pixels; at least 4 per side)"


@pytest.mark.slow  # worker processes, then a real SIGTERM or SIGHUP
@pytest.mark.parametrize("signame, code, line", [("SIGTERM", 143, "Terminated."), ("SIGHUP", 129, "Hung up.")])
def test_sigterm_ends_a_worker_batch_cleanly(tmp_path, model_dir, signame, code, line):
    """SIGTERM into `vectorize --jobs 2`: exit 143, one `Terminated.` line, no resource-tracker
    warning, no traceback, no worker left, every SVG written complete and no temp file. SIGHUP
    (a closed terminal) the same, exit 129 (it printed a worker's traceback and left 4 processes)."""
    import signal
    import time

    d = tmp_path / "in"
    d.mkdir()
    for i in range(400):  # far more than are done when the first are written
        glyph_like(32 + i % 3).save(d / f"g{i:03d}.png")
    out = tmp_path / "out"
    p = subprocess.Popen(EXE + ["vectorize", str(d), "-o", str(out), "--model", model_dir, "--jobs", "2"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while time.time() < deadline and not (out.exists() and any(out.glob("g*.svg"))):
        time.sleep(0.2)  # until the first SVGs are written (not only their temp files)
    p.send_signal(getattr(signal, signame))
    err = p.communicate(timeout=30)[1]
    assert p.returncode == code, err
    assert "resource_tracker" not in err and "Traceback" not in err and err.strip().endswith(line), err
    time.sleep(3)
    left = subprocess.run(["pgrep", "-f", str(d)], capture_output=True, text=True).stdout.split()
    assert left == []
    written = list(out.iterdir())
    assert written and all(not f.name.startswith(".") for f in written)
    for f in written:
        check_svg(f.read_text(), 32 + int(f.stem[1:]) % 3, 32 + int(f.stem[1:]) % 3)


@pytest.mark.parametrize("args, pooled", [([], True), (["--parts", "model"], False)])
def test_no_refine_folders_use_worker_processes_only_for_the_clean_work(tmp_path, model_dir, monkeypatch, args, pooled):
    """--no-refine on a folder of 64+ pictures: drawing each guess clean is work per picture, so
    the worker processes of a refined folder share it; the model's own paths (--parts model) are
    one batched forward pass, which a pool would only slow down."""
    import im2vec_cli.parallel as parallel
    import im2vec_cli.runtime as runtime
    from im2vec_cli.vector import VectorImage

    calls = []

    def fake(chunks, model_name, **kw):  # the pool's contract: a list of results per chunk
        calls.append(kw)
        for c in chunks:
            yield [VectorImage(a.shape[1], a.shape[0]) for a in c]

    monkeypatch.setattr(parallel, "vectorize_chunks", fake)
    monkeypatch.setattr(runtime, "free_cores", lambda: 2)
    d = tmp_path / "in"
    d.mkdir()
    for i in range(64):
        glyph_like(32).save(d / f"g{i:03d}.png")
    res = CliRunner().invoke(cli, ["vectorize", str(d), "-o", str(tmp_path / "out"), "--model", model_dir,
                                   "--no-refine", *args])
    assert res.exit_code == 0, res.output
    assert len(list((tmp_path / "out").glob("*.svg"))) == 64
    assert [(c["jobs"], c["options"].refine, c["options"].parts) for c in calls] == (
        [(2, False, "clean")] if pooled else [])


def _children(pid: int) -> list[int]:
    """The processes whose parent is ``pid`` (from /proc)."""
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    if int(f.read().rsplit(")", 1)[1].split()[1]) == pid:
                        out.append(int(d))
            except (OSError, ValueError, IndexError):
                pass
    return out


def _workers(pid: int) -> list[int]:
    """The pool workers of the `im2vec` process ``pid``: the forkserver's children."""
    servers = []
    for kid in _children(pid):
        try:
            with open(f"/proc/{kid}/cmdline", "rb") as f:
                if b"forkserver" in f.read():
                    servers.append(kid)
        except OSError:
            pass
    return [w for s in servers for w in _children(s)]


@pytest.mark.slow  # worker processes, SIGKILLed from outside
@pytest.mark.parametrize("kills", ["once", "every worker"])
def test_a_killed_worker_is_noticed(tmp_path, model_dir, kills):
    """SIGKILL into a worker of `vectorize --jobs 2` (it hung until killed, 0 SVGs written). Once:
    a warning line, its pictures vectorized again, all written, exit 0. Every worker, again and
    again: each picture in flight fails by name, the ones done before are written, exit 1; it
    ends, with no worker left."""
    import signal
    import time

    d = tmp_path / "in"
    d.mkdir()
    for i in range(300):
        glyph_like(32 + i % 3).save(d / f"g{i:03d}.png")
    out = tmp_path / "out"
    p = subprocess.Popen(EXE + ["vectorize", str(d), "-o", str(out), "--model", model_dir, "--jobs", "2"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline, killed = time.time() + 150, 0
    while p.poll() is None and time.time() < deadline:
        if out.exists() and any(out.glob("g*.svg")) and (kills == "every worker" or not killed):
            for w in _workers(p.pid)[: 1 if kills == "once" else None]:
                try:
                    os.kill(w, signal.SIGKILL)
                    killed += 1
                except ProcessLookupError:
                    pass
        time.sleep(0.2)
    err = p.communicate(timeout=60)[1]
    assert killed >= 1 and "Traceback" not in err, err
    written = sorted(f.name for f in out.iterdir())
    assert all(not f.startswith(".") for f in written)
    lines = err.strip().splitlines()
    assert sum("a worker process died" in line and line.startswith("Warning:") for line in lines) >= 1, (killed, err)
    if kills == "once":
        assert p.returncode == 0, err
        assert len(written) == 300
    else:
        assert p.returncode == 1, err
        failed = {line.split(":")[1].strip() for line in lines if "died on it" in line}
        assert failed and lines[-1] == f"Error: {len(failed)} of 300 inputs failed"
        assert sorted(failed) == sorted(str(d / f"g{i:03d}.png") for i in range(300) if f"g{i:03d}.svg" not in written)
    time.sleep(2)
    assert _workers(p.pid) == [] and subprocess.run(["pgrep", "-f", str(d)], capture_output=True).stdout == b""


def test_jobs_are_capped_by_the_work(tmp_path, model_dir, monkeypatch):
    """`-j 6` on 40 refined pictures (two chunks of 32) starts two workers, not six model copies;
    on 2 (one chunk) none: the work runs here. Pictures each traced alone (a draft) are chunked
    finer, in sixteen chunks or more: 2 of them start 2 workers (issue 70: every core from two
    pictures up), 40 of them all six."""
    import im2vec_cli.parallel as parallel
    from im2vec_cli.vector import VectorImage

    calls = []

    def fake(chunks, model_name, **kw):
        calls.append(kw["jobs"])
        for c in chunks:
            yield [VectorImage(a.shape[1], a.shape[0]) for a in c]

    monkeypatch.setattr(parallel, "vectorize_chunks", fake)
    for n, effort, want in ((40, "fast", [2]), (2, "fast", []), (2, "draft", [2]), (40, "draft", [6])):
        d = tmp_path / f"in{n}{effort}"
        d.mkdir()
        for i in range(n):
            glyph_like(32).save(d / f"g{i:03d}.png")
        calls.clear()
        out = tmp_path / f"out{n}{effort}"
        res = CliRunner().invoke(cli, ["vectorize", str(d), "-o", str(out), "--model", model_dir, "-j", "6",
                                       "--effort", effort])
        assert res.exit_code == 0, res.output
        assert calls == want and len(list(out.glob("*.svg"))) == n
