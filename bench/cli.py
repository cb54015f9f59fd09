"""Command-line latency, one picture start to finish (issues "Inference commands" and
"`im2vec vectorize glyph.png -o glyph.svg` in about two seconds, busy machine or not"): the
whole `im2vec vectorize IMG -o OUT` process, defaults, against `python -c "import torch"`, in
paired runs on a quiet machine and with one core kept busy by another program.

Pictures (neither from a set any shipped model trained on):

- **glyph 64 px**: ``examples/glyph_a.png`` (the README's first invocation);
- **glyph 512 px**: "g" of GNU FreeSerif (Debian fonts-freefont-ttf, not in
  shared/data/font-packages.txt) drawn 400 px tall on a 512 px canvas with Pillow.

Each round runs, one after the other: ``python -c "import torch"``, then each command on each
picture, with this checkout and (``--before DIR``, a checkout of an older commit, e.g.
``git worktree add DIR 549518d``) with that one; ``--rounds`` rounds per condition. Reported:
the median wall time of each command, the median of its per-round ratio to the import of
torch in the same round, and its peak memory (max RSS of the process). "busy" runs a
``yes > /dev/null`` loop beside every command (one of the 2 cores taken, as on a user's
laptop). A first, unmeasured round warms the page cache and writes the bytecode caches of both
checkouts (``PYTHONDONTWRITEBYTECODE`` is dropped, as an installed package has its ``.pyc``). Also timed: ``im2vec --help``, ``vectorize --no-refine`` and ``--effort best``.

The import table: one ``python -X importtime -m im2vec_cli vectorize`` of each picture, the
self time of every module summed by top-level package (importtime's own overhead included,
so the sum exceeds a plain run's import time).

Every output is checked: each SVG is compared byte for byte with the one the other checkout
wrote for the same picture (identical or not is printed; the outline benches judge any change).

Run: ``make bench-cli`` or ``python bench/cli.py [--rounds 7] [--before DIR]
[--markdown docs/bench-cli.md]``.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FREESERIF = "/usr/share/fonts/truetype/freefont/FreeSerif.ttf"


def pictures(folder: Path) -> dict[str, Path]:
    from PIL import Image, ImageDraw, ImageFont

    big = Image.new("L", (512, 512), 255)
    font = ImageFont.truetype(FREESERIF, 400)
    ImageDraw.Draw(big).text((256, 256), "g", font=font, fill=0, anchor="mm")
    big.save(folder / "g512.png")
    return {"glyph 64 px": ROOT / "examples" / "glyph_a.png", "glyph 512 px": folder / "g512.png"}


def run(cmd: list[str], env: dict | None = None) -> tuple[float, float]:
    """Wall seconds and peak memory (MiB) of one command, which must succeed."""
    env = {k: v for k, v in {**os.environ, **(env or {})}.items() if k != "PYTHONDONTWRITEBYTECODE"}
    t = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode()
    proc.stderr.close()
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}): {err.strip()[-400:]}")
    return wall, usage.ru_maxrss / 1024


def commands(pics: dict[str, Path], out: Path, before: Path | None) -> dict[str, tuple[list[str], dict | None]]:
    """label -> (argv, extra environment)."""
    py = sys.executable
    code = {"this": None}
    if before is not None:
        code["before"] = {"PYTHONPATH": str(before / "src")}
    cmds = {"import torch": ([py, "-c", "import torch"], None)}
    for who, env in code.items():
        cmds[f"im2vec --help ({who})"] = ([py, "-m", "im2vec_cli", "--help"], env)
        for name, png in pics.items():
            cmds[f"vectorize, {name} ({who})"] = (
                [py, "-m", "im2vec_cli", "vectorize", str(png), "-o", str(out / f"{who}-{png.stem}.svg")], env)
        png = pics["glyph 64 px"]
        cmds[f"vectorize --no-refine, glyph 64 px ({who})"] = (
            [py, "-m", "im2vec_cli", "vectorize", str(png), "--no-refine", "-o", str(out / f"{who}-nr.svg")], env)
        cmds[f"vectorize --effort best, glyph 64 px ({who})"] = (
            [py, "-m", "im2vec_cli", "vectorize", str(png), "--effort", "best", "-o", str(out / f"{who}-best.svg")],
            env)
    return cmds


def measure(cmds: dict, rounds: int, busy: bool) -> dict[str, dict]:
    times: dict[str, list[float]] = {k: [] for k in cmds}
    mem: dict[str, float] = dict.fromkeys(cmds, 0.0)
    hog = subprocess.Popen(["yes"], stdout=subprocess.DEVNULL) if busy else None
    try:
        for argv, env in cmds.values():  # warm the page cache, unmeasured
            run(argv, env)
        for _ in range(rounds):
            for label, (argv, env) in cmds.items():
                wall, rss = run(argv, env)
                times[label].append(wall)
                mem[label] = max(mem[label], rss)
    finally:
        if hog is not None:
            hog.kill()
            hog.wait()
    base = times["import torch"]
    return {k: {"median": statistics.median(v), "ratio": statistics.median(a / b for a, b in zip(v, base)),
                "mem": mem[k]} for k, v in times.items()}


def table(results: dict[str, dict]) -> str:
    lines = ["| command | quiet: median s | quiet: x import torch | busy: median s | busy: x import torch | "
             "peak MiB |", "|---|---|---|---|---|---|"]
    for label in results["quiet"]:
        q, b = results["quiet"][label], results["busy"][label]
        lines.append(f"| {label} | {q['median']:.2f} | {q['ratio']:.2f} | {b['median']:.2f} | {b['ratio']:.2f} | "
                     f"{max(q['mem'], b['mem']):.0f} |")
    return "\n".join(lines)


def import_table(pics: dict[str, Path], out: Path) -> str:
    """Self import time by top-level package of one default ``vectorize`` of each picture."""
    cols = {}
    for name, png in pics.items():
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        r = subprocess.run([sys.executable, "-X", "importtime", "-m", "im2vec_cli", "vectorize", str(png), "-o",
                            str(out / "imports.svg")], capture_output=True, text=True, check=True, env=env)
        total: dict[str, float] = {}
        for line in r.stderr.splitlines():
            m = re.match(r"import time:\s+(\d+) \|\s+\d+ \|\s*(\S+)", line)
            if m:
                top = m[2].split(".")[0]
                total[top] = total.get(top, 0.0) + int(m[1]) / 1000
        cols[name] = total
    names = list(pics)
    order = sorted({k for c in cols.values() for k in c}, key=lambda k: -max(c.get(k, 0) for c in cols.values()))
    shown = [k for k in order if max(c.get(k, 0) for c in cols.values()) >= 5]
    lines = ["| package | " + " | ".join(f"{n}: ms" for n in names) + " |", "|---" * (len(names) + 1) + "|"]
    for k in shown:
        lines.append(f"| {k} | " + " | ".join(f"{cols[n].get(k, 0):.0f}" for n in names) + " |")
    lines.append("| (all) | " + " | ".join(f"{sum(cols[n].values()):.0f}" for n in names) + " |")
    return "\n".join(lines)


def same_outputs(out: Path) -> list[str]:
    notes = []
    for mine in sorted(out.glob("this-*.svg")):
        other = out / mine.name.replace("this-", "before-", 1)
        if other.exists():
            same = mine.read_bytes() == other.read_bytes()
            notes.append(f"{mine.name[5:]}: {'byte-identical' if same else 'differs'} before and after")
    return notes


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--before", type=Path, default=None, help="a checkout of an older commit to run beside this one")
    ap.add_argument("--markdown", default=None)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        pics = pictures(out)
        cmds = commands(pics, out, args.before)
        results = {}
        for cond in ("quiet", "busy"):
            results[cond] = measure(cmds, args.rounds, cond == "busy")
            print(f"{cond}: " + ", ".join(f"{k} {v['median']:.2f} s ({v['ratio']:.2f}x)" for k, v in results[cond].items()),
                  flush=True)
        notes = same_outputs(out)
        imports = import_table(pics, out)
    text = (f"## One picture, start to finish (`make bench-cli`)\n\n"
            f"Written by bench/cli.py ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
            f"{os.cpu_count()} CPU cores, {args.rounds} paired rounds per condition; busy: a `yes` loop holds one "
            f"core). Wall time of the whole process, and its median ratio to `python -c \"import torch\"` in the "
            f"same round.\n\n{table(results)}\n\n" + "".join(f"- {n}\n" for n in notes)
            + f"\nWhat a default `vectorize` imports (`python -X importtime`, self time summed by top-level package; "
            f"packages under 5 ms left out):\n\n{imports}\n")
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(f"# One picture against `import torch` (`make bench-cli`)\n\n{text}")


if __name__ == "__main__":
    main()
