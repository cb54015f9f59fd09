"""The cases of issue "Safety" as real processes, as the user would meet them: each under an
8 GiB address-space cap (``RLIMIT_AS``), with a 60 s limit. Prints one table row per case:
exit code, ``Error:`` lines, whether a traceback appeared, seconds, and for `render` and
`eval` cases the seconds from a SIGINT (sent 1 s in) to the exit.

    python bench/safety.py [--out docs/safety-run.md]

It prints figures; it passes or fails nothing (the tests in tests/cli/test_safety.py do).
"""

from __future__ import annotations

import argparse
import os
import random
import resource
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

CAP = 8 * 2**30
LIMIT = 60
EXE = [sys.executable, "-m", "im2vec_cli"]


def _cap():
    resource.setrlimit(resource.RLIMIT_AS, (CAP, CAP))


def run(args, cwd, interrupt=False, stdin=None):
    """(exit code, Error lines, traceback?, seconds, seconds from SIGINT to exit or None)."""
    start = time.perf_counter()
    p = subprocess.Popen(EXE + args, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=_cap, stdin=stdin)
    answer = None
    try:
        if interrupt:
            try:
                p.wait(1.0)
            except subprocess.TimeoutExpired:
                sent = time.perf_counter()
                p.send_signal(signal.SIGINT)
                p.wait(LIMIT)
                answer = time.perf_counter() - sent
        out, err = p.communicate(timeout=LIMIT)
    except subprocess.TimeoutExpired:
        p.kill()
        out, err = p.communicate()
        return "killed", [], "Traceback" in err, time.perf_counter() - start, answer
    errors = [x for x in err.splitlines() if x.startswith("Error:")]
    return p.returncode, errors, "Traceback" in err, time.perf_counter() - start, answer


def svg(body, size=100):
    return f'<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{size}">{body}</svg>'


CASES = {  # name -> the arguments of the case, run in make()'s folder
    "vectorize -o /dev/null": ["vectorize", "g.png", "-o", "/dev/null"],
    "vectorize -o /dev/full": ["vectorize", "g.png", "-o", "/dev/full"],
    "vectorize (1024 px JPEG)": ["vectorize", "big.jpg", "-o", "big.svg"],
    "render the vectorized 1024 px JPEG": ["render", "big.svg", "-o", "big.png"],
    "render dashed ring": ["render", "ring.svg", "-o", "ring.png"],
    "render dasharray 0.001": ["render", "dash001.svg", "-o", "d1.png"],
    "render dasharray 0.0125": ["render", "dash0125.svg", "-o", "d2.png"],
    "render 5,000-segment polygon": ["render", "poly5000.svg", "-o", "p1.png"],
    "render 20,000-segment polygon": ["render", "poly20000.svg", "-o", "p2.png"],
    "render 199,000-segment polygon": ["render", "poly199000.svg", "-o", "p3.png"],
    "render 4,900 rectangles": ["render", "rects4900.svg", "-o", "r.png"],
    "render clip-path": ["render", "clip.svg", "-o", "c.png"],
    "render visibility hidden": ["render", "hidden.svg", "-o", "h.png"],
    "eval on a folder holding dasharray 0.001": ["eval", "--data", "evaldata", "-o", "e.json"],
    "train on 1 image": ["train", "train1", "--config", "c.json", "--out", "run1", "--device", "cpu"],
    "train on 2 images": ["train", "train2", "--config", "c.json", "--out", "run2", "--device", "cpu"],
    "train onto the finished run": ["train", "train2", "--config", "c.json", "--out", "run2", "--device", "cpu"],
    "export onto a model folder": ["export", "run2", "-o", "run2/model"],
    "fit-prior without -o": ["fit-prior", "train2", "--model", "run2/model"],
    "./fonts beside the default model": ["vectorize", "g.png", "-o", "f.svg", "--no-refine"],
    "- mixed with files": ["vectorize", "-", "g.png", "-o", "mixed"],
    "sample -o -": ["sample", "-o", "-"],
}


def make(d: Path) -> dict[str, list[str]]:
    """The input files, and the cases: name -> arguments."""
    rng = random.Random(0)
    g = Image.new("RGB", (64, 64), "white")
    ImageDraw.Draw(g).ellipse((10, 8, 54, 56), outline="black", width=8)
    g.save(d / "g.png")
    big = Image.new("RGB", (1024, 1024), "white")
    dr = ImageDraw.Draw(big)
    for _ in range(60):
        x, y, r = rng.uniform(50, 970), rng.uniform(50, 970), rng.uniform(10, 60)
        dr.ellipse((x - r, y - r, x + r, y + r), fill=rng.choice(["black", "#c03030", "#3050c0"]))
    big.save(d / "big.jpg", quality=40)
    (d / "ring.svg").write_text(svg('<circle cx="50" cy="50" r="40" fill="none" stroke="black" stroke-width="6" '
                                    'stroke-dasharray="0.3 0.3"/>'))
    line = '<line x1="0" y1="50" x2="100" y2="50" stroke="black" stroke-width="2" stroke-dasharray="{}"/>'
    (d / "dash001.svg").write_text(svg(line.format("0.001")))
    (d / "dash0125.svg").write_text(svg(line.format("0.0125")))
    for n in (5000, 20000, 199000):
        pts = " ".join(f"{rng.uniform(0, 1000):.1f},{rng.uniform(0, 1000):.1f}" for _ in range(n))
        (d / f"poly{n}.svg").write_text(svg(f'<polygon points="{pts}"/>', 1000))
    (d / "rects4900.svg").write_text(svg("".join(f'<rect x="{(i % 70) * 14}" y="{(i // 70) * 14}" width="10" '
                                                 f'height="10"/>' for i in range(4900)), 1000))
    (d / "clip.svg").write_text(svg('<defs><clipPath id="c"><rect width="20" height="20"/></clipPath></defs>'
                                    '<rect width="50" height="50" clip-path="url(#c)"/>'))
    (d / "hidden.svg").write_text(svg('<rect width="50" height="50" visibility="hidden"/>'
                                      '<rect x="60" y="60" width="20" height="20"/>'))
    data = d / "evaldata"
    data.mkdir()
    g.save(data / "a.png")
    (data / "a.svg").write_text((d / "dash001.svg").read_text())
    os.mkfifo(d / "fifo")
    for n in (1, 2):
        (d / f"train{n}").mkdir()
        for i in range(n):
            g.rotate(10 * i).save(d / f"train{n}" / f"{i}.png")
    (d / "c.json").write_text('{"model": {"image_size": 32, "latent": 8, "paths": 2}, '
                              '"train": {"batch": 2, "steps": 2, "workers": 1}}')
    (d / "fonts").mkdir()
    return CASES


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None, help="Also write the table to this markdown file.")
    args = ap.parse_args()
    rows = ["| case | exit | `Error:` lines | traceback | s | SIGINT answered in (s) |", "|---|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        cases = make(d)
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", "import torch"], check=True)
        rows.append(f"| (`python -c 'import torch'`, for scale) | 0 | 0 | no | {time.perf_counter() - start:.1f} | |")
        print(rows[-1], flush=True)
        for name, argv in cases.items():
            code, errors, tb, secs, _ = run(argv, d, stdin=subprocess.DEVNULL)
            answer = ""
            if argv[0] in ("render", "eval") and secs > 1.5:
                answer = run(argv, d, interrupt=True, stdin=subprocess.DEVNULL)[4]
                answer = f"{answer:.2f}" if answer is not None else "ended first"
            note = errors[0][7:90] if errors else ""
            rows.append(f"| {name} | {code} | {len(errors)} {note} | {'yes' if tb else 'no'} | {secs:.1f} | {answer} |")
            print(rows[-1], flush=True)
        dev = os.stat("/dev/full")
        rows.append(f"\n/dev/full is still a character device: {os.path.exists('/dev/full') and (dev.st_mode & 0o170000) == 0o020000}; "
                    f"run as uid {os.getuid()}, RLIMIT_AS {CAP // 2**30} GiB, {np.__name__} {np.__version__}.")
        print(rows[-1])
    if args.out:
        Path(args.out).write_text("\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
