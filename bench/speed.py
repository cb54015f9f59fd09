"""As fast as vtracer (issue 70): im2vec and vtracer on the same pictures, side by side in one run.

Sets (none of them in any shipped model's training data):

- **made**: bench/realworld.py's scans, logos, pixel art and line art of at most 600 px a side
  (GNU FreeFont, Lato, Font Awesome Free 7.3.1, OpenMoji 1.2.29; ``make bench-sets``);
- **real**: files that exist as they are: Adwaita desktop icons at 512, 96 and 48 px (Debian
  adwaita-icon-theme) and scikit-image's sample pictures (photos, a scanned page and text, a
  silhouette, its logo).

Rows: one call with its process start (the median over pictures of each kind, each tool in a fresh
process: ``im2vec vectorize p -o out`` against ``python -c 'vtracer.convert_image_to_svg_py(...)'``);
each set as one folder in one process (vtracer: one Python process looping over the files);
one 64 px glyph with the default refinement against ``python -c 'import torch'``; and
``--no-refine`` of one glyph once the model is loaded. With ``--before DIR`` (a checkout) each
folder's SVGs are compared byte for byte with that checkout's. A profile of one 512 px logo
closes the report.

Run: ``make bench-speed`` (writes the section of docs/BENCHMARKS.md between its speed markers), or
``python bench/speed.py [--before DIR] [--rounds N]``.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import pstats
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))

ADWAITA = Path("/usr/share/icons/Adwaita")
REAL_ICONS = [("512x512/devices", 4), ("512x512/places", 3), ("512x512/mimetypes", 3), ("512x512/emblems", 2),
              ("96x96/status", 4), ("96x96/categories", 2), ("48x48/legacy", 6)]
SKIMAGE = ["camera", "coins", "text", "page", "horse", "astronaut", "coffee", "chelsea", "rocket", "clock", "logo",
           "colorwheel"]
MADE_SETS = ("scans", "logos", "pixel", "line")
MAX_SIDE = 600
BEGIN, END = "<!-- speed:begin -->", "<!-- speed:end -->"


def real_files(out: Path) -> list[Path]:
    """The real pictures, copied (icons) or written as PNG (scikit-image's arrays) into ``out``."""
    import skimage.data

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for folder, n in REAL_ICONS:
        for src in sorted((ADWAITA / folder).glob("*.png"))[:n]:
            dst = out / f"adwaita-{folder.split('x')[0]}-{src.name.split('.')[0]}.png"
            dst.write_bytes(src.read_bytes())
            paths.append(dst)
    for name in SKIMAGE:
        arr = getattr(skimage.data, name)()
        arr = (arr * 255).astype(np.uint8) if arr.dtype == bool else arr
        dst = out / f"skimage-{name}.png"
        Image.fromarray(arr).save(dst)
        paths.append(dst)
    return paths


def made_files(out: Path, src: Path) -> list[Path]:
    """bench/realworld.py's made pictures of at most ``MAX_SIDE`` px, as the files it feeds the tools."""
    from realworld_sets import make_sets

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for kind, rows in make_sets(src, list(MADE_SETS), None).items():
        for r in rows:
            if max(Image.open(io.BytesIO(r["input"])).size) > MAX_SIDE:
                continue
            ext = ".jpg" if r["input"][:2] == b"\xff\xd8" else ".png"
            dst = out / (kind + "-" + re.sub(r"[^a-z0-9]+", "-", r["name"].lower()).strip("-") + ext)
            dst.write_bytes(r["input"])
            paths.append(dst)
    return paths


def _run(cmd: list[str], env: dict | None = None) -> float:
    t = time.perf_counter()
    proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    wall = time.perf_counter() - t
    if proc.returncode:
        raise RuntimeError(f"{' '.join(cmd[:4])}...: {proc.stderr.decode().strip().splitlines()[-1:]}")
    return wall


def im2vec_cmd(src: Path, *args: str) -> tuple[list[str], dict]:
    """``python -m im2vec_cli ARGS`` from the checkout ``src``."""
    return [sys.executable, "-m", "im2vec_cli", *args], {**os.environ, "PYTHONPATH": str(src / "src")}


VT_ONE = "import sys, vtracer; vtracer.convert_image_to_svg_py(sys.argv[1], sys.argv[2])"
VT_FOLDER = ("import sys, os, vtracer\nfor f in sorted(os.listdir(sys.argv[1])):\n"
             "    vtracer.convert_image_to_svg_py(os.path.join(sys.argv[1], f), os.path.join(sys.argv[2], f + '.svg'))")


def one_calls(paths: list[Path], work: Path, rounds: int) -> tuple[float, float]:
    """Median wall of one call with its process start, im2vec and vtracer, over ``paths`` x ``rounds``."""
    ours, theirs = [], []
    for _ in range(rounds):
        for p in paths:
            out = work / "one.svg"
            out.unlink(missing_ok=True)
            ours.append(_run(*im2vec_cmd(ROOT, "vectorize", str(p), "-o", str(out))))
            theirs.append(_run([sys.executable, "-c", VT_ONE, str(p), str(work / "vt.svg")]))
    return statistics.median(ours), statistics.median(theirs)


def folder(paths: list[Path], work: Path, name: str, src: Path = ROOT) -> tuple[float, float, Path]:
    """Wall of the pictures as one folder in one process: im2vec (checkout ``src``), vtracer; and im2vec's SVGs."""
    inp = work / f"{name}-in"
    inp.mkdir(exist_ok=True)
    for p in paths:
        (inp / p.name).write_bytes(p.read_bytes())
    out = work / f"{name}-{src.name}"
    ours = _run(*im2vec_cmd(src, "vectorize", str(inp), "-o", str(out) + "/"))
    vt = work / f"{name}-vt"
    vt.mkdir(exist_ok=True)
    theirs = _run([sys.executable, "-c", VT_FOLDER, str(inp), str(vt)])
    return ours, theirs, out


def same_svgs(a: Path, b: Path, inputs: Path) -> tuple[int, int, list[str]]:
    """How many of ``a``'s SVGs are byte-identical to ``b``'s, of how many, and for each that is
    not: its name and both SVGs' MSE against its input picture (rendered at 1x by cairo)."""
    sys.path.insert(0, str(ROOT / "src"))
    from im2vec_cli.files import load_picture
    from im2vec_cli.vector import rasterize_svg

    names = sorted(p.name for p in a.glob("*.svg"))
    same, odd = 0, []
    for n in names:
        x, y = (a / n).read_text(), (b / n).read_text() if (b / n).exists() else ""
        if x == y:
            same += 1
            continue
        pic = load_picture(next(inputs.glob(n[:-4] + ".*")))
        h, w, _ = pic.shape
        mse = [float(((rasterize_svg(t, w, h) - pic) ** 2).mean()) if t else float("nan") for t in (x, y)]
        odd.append(f"{n[:-4]} (MSE against the picture {mse[0]:.5f}, before {mse[1]:.5f})")
    return same, len(names), odd


def compiled(src: Path) -> None:
    """The bytecode of the checkout ``src``'s package written, as ``pip install`` writes it for an
    installed package (an editable install under ``PYTHONDONTWRITEBYTECODE`` has none, and each
    process compiled im2vec's modules anew: 0.05-0.1 s of a call)."""
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(src / "src" / "im2vec_cli")], check=True)


def glyph_rows(work: Path, rounds: int) -> tuple[float, float, float]:
    """One 64 px glyph with the default refinement (a process each) against ``import torch``, and the
    median seconds of ``--no-refine`` of a glyph once the model is loaded (in this process)."""
    glyph = ROOT / "examples" / "glyph_a.png"
    ours = statistics.median(_run(*im2vec_cmd(ROOT, "vectorize", str(glyph), "-o", str(work / f"g{i}.svg")))
                             for i in range(rounds))
    torch_only = statistics.median(_run([sys.executable, "-c", "import torch"]) for _ in range(rounds))
    sys.path.insert(0, str(ROOT / "src"))
    from im2vec_cli import api

    model = api.load_model("fonts", "cpu")
    api.vectorize(str(glyph), model, refine=False)  # the first call's one-off costs apart
    times = []
    for _ in range(max(5, rounds)):
        t = time.perf_counter()
        api.vectorize(str(glyph), model, refine=False)
        times.append(time.perf_counter() - t)
    return ours, torch_only, statistics.median(times)


STAGES = [  # (what, the function whose cumulative time it is)
    ("read the file", "files.py:load_picture"),
    ("read the picture (its kind, the clean picture)", "read.py:read"),
    ("regions traced", "regions.py:trace"),
    ("  of which the palette (colour pictures)", "palette.py:quantize"),
    ("  of which a photo's pieces cut", "photo.py:pieces"),
    ("  of which each piece's outline (edge field, reach, level set)", "regions.py:_stacked_regions"),
    ("rings fitted with cubics", "fit.py:fit_rings"),
    ("crossings untangled", "untangle.py:untangle"),
    ("SVG written", "svg.py:to_svg"),
]
FLOOR = ("import im2vec_cli.cli, im2vec_cli.api, cv2, contourpy, pathops, PIL.PngImagePlugin, "
         "xml.etree.ElementTree")  # what a traced picture's command imports


def profile(path: Path, rounds: int = 3) -> str:
    """Where one ``vectorize`` of ``path`` spends its time: the interpreter with the imports a traced
    picture needs (a fresh process, median of ``rounds``), and the stages of a second ``vectorize``
    in one process under cProfile (which slows each stage: read the shares)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    floor = statistics.median(_run([sys.executable, "-c", FLOOR], env) for _ in range(rounds))
    bare = statistics.median(_run([sys.executable, "-c", "import numpy"]) for _ in range(rounds))
    code = ("import cProfile, pstats, sys\nfrom im2vec_cli import api\napi.vectorize(sys.argv[1])\n"
            "p = cProfile.Profile()\np.enable()\napi.vectorize(sys.argv[1]).to_svg()\np.disable()\n"
            "p.dump_stats(sys.argv[2])\n")
    stats_file = Path(tempfile.mkdtemp()) / "vectorize.prof"
    subprocess.run([sys.executable, "-c", code, str(path), str(stats_file)], env=env, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    st = pstats.Stats(str(stats_file))
    whole = max(v[3] for v in st.stats.values())
    cum: dict[str, float] = {}
    for (file, _, fn), v in st.stats.items():
        key = f"{Path(file).name}:{fn}"
        cum[key] = max(cum.get(key, 0.0), v[3])
    lines = [f"| {what.replace('  ', '&nbsp;&nbsp;')} | {cum.get(key, 0.0):.3f} | {cum.get(key, 0.0) / whole:.0%} |"
             for what, key in STAGES]
    return (f"A fresh process that imports what a traced picture needs (Python, NumPy, OpenCV, Pillow, click, "
            f"ElementTree, contourpy, skia-pathops, im2vec's CLI): {floor:.2f} s "
            f"(`python -c 'import numpy'`: {bare:.2f} s). The work itself, profiled:\n\n"
            f"| stage | s (profiled) | share |\n|---|---|---|\n| `api.vectorize`, warm | {whole:.3f} | 100% |\n"
            + "\n".join(lines))


BREAKDOWN = """
import json, sys, time
from im2vec_cli import api
from im2vec_cli.files import load_picture
from im2vec_cli.trace.read import read
paths = sys.argv[1:]
api.vectorize(paths[-1])  # the first call's one-off costs apart (not the model's: a polished picture's below)
rows = []
for p in paths:
    t = time.perf_counter()
    api.vectorize(p).to_svg()
    took = time.perf_counter() - t
    pic = load_picture(p)
    r = read(pic.astype('float64'))
    rows.append((p, r.kind, bool(r.polish and max(pic.shape[:2]) <= 128), took))
print(json.dumps(rows))
"""


def real_breakdown(paths: list[Path]) -> str:
    """Where a folder of ``paths`` spends its time: each picture vectorized in one process (one
    after another, the model loaded at the first picture that is polished), summed by what it was
    read as and whether it was polished through torch."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    out = subprocess.run([sys.executable, "-c", BREAKDOWN, *map(str, paths)], env=env, check=True,
                         capture_output=True, text=True).stdout
    groups: dict[str, list[float]] = {}
    for _, kind, polished, took in json.loads(out.strip().splitlines()[-1]):
        groups.setdefault(f"{kind}, polished (torch)" if polished else kind, []).append(took)
    whole = sum(map(sum, groups.values()))
    lines = ["| read as | pictures | s in one process | share |", "|---|---|---|---|"]
    lines += [f"| {g} | {len(t)} | {sum(t):.2f} | {sum(t) / whole:.0%} |"
              for g, t in sorted(groups.items(), key=lambda kv: -sum(kv[1]))]
    return "\n".join(lines + [f"| all | {len(paths)} | {whole:.2f} | 100% |"])


def kinds(paths: list[Path], per_kind: int) -> list[Path]:
    """``per_kind`` pictures of each kind (the name's first word), for the one-call rows."""
    out, count = [], {}
    for p in paths:
        k = p.name.split("-")[0]
        if count.get(k, 0) < per_kind:
            out.append(p)
            count[k] = count.get(k, 0) + 1
    return out


def report(rows: list[tuple[str, float, float]], notes: list[str], prof: str) -> str:
    """The markdown section: each row's figures and ratio, then the notes and the profile."""
    lines = ["| | im2vec | vtracer | ratio |", "|---|---|---|---|"]
    lines += [f"| {name} | {a:.2f} s | {b:.2f} s | {a / b:.1f}x |" for name, a, b in rows]
    return "\n".join(lines + [""] + notes + ["", prof])


def write_section(path: Path, text: str) -> None:
    """Replace what lies between the speed markers of ``path`` with ``text``."""
    doc = path.read_text()
    start, end = doc.index(BEGIN) + len(BEGIN), doc.index(END)
    path.write_text(doc[:start] + "\n" + text + "\n" + doc[end:])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--src", type=Path, default=ROOT / "bench" / ".sets", help="bench-sets' folder (fa, om)")
    ap.add_argument("--before", type=Path, default=None, help="a checkout whose SVGs each folder's are compared with")
    ap.add_argument("--rounds", type=int, default=1, help="one-call rounds over the pictures")
    ap.add_argument("--markdown", type=Path, default=None, help="write the section between the speed markers here")
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="im2vec-speed-"))
    made, real = made_files(work / "made", args.src), real_files(work / "real")
    for src in (ROOT, args.before) if args.before else (ROOT,):  # each checkout's modules as an installed package
        compiled(src)  # has them (pip compiles them): no run pays for compiling its own sources
    rows, notes = [], []
    a, b = one_calls(kinds(made + real, 2), work, args.rounds)
    rows.append((f"one call with its process start (median, {len(kinds(made + real, 2))} pictures)", a, b))
    for name, paths in (("made", made), ("real", real)):
        ours, theirs, out = folder(paths, work, name)
        rows.append((f"a folder of the {len(paths)} {name} pictures in one process", ours, theirs))
        if args.before:
            before, _, old = folder(paths, work, name, args.before.resolve())
            same, n, odd = same_svgs(out, old, work / f"{name}-in")
            notes.append(f"- {name}: {same} of {n} SVGs byte-identical to {args.before.name}'s "
                         f"(which took {before:.2f} s on the folder in this run)"
                         + (f"; the others: {', '.join(odd)}" if odd else ""))
    glyph, torch_only, no_refine = glyph_rows(work, max(3, args.rounds))
    notes.append(f"- one 64 px glyph, default refinement, process start included: {glyph:.2f} s; "
                 f"`python -c 'import torch'`: {torch_only:.2f} s ({glyph / torch_only:.2f}x)")
    notes.append(f"- `--no-refine` of one 64 px glyph once the model is loaded: {no_refine * 1000:.0f} ms")
    logo = next(p for p in real if "512" in p.name)
    photo = next(p for p in real if p.name == "skimage-coffee.png")
    text = report(rows, notes, f"Where the real folder's time goes: each of its pictures in one process, one "
                  f"after another (the folder row runs them on the workers `plan_workers` picks; the first "
                  f"picture polished imports torch and loads the model, about 1.5 s):\n\n"
                  f"{real_breakdown(real)}\n\nWhere one call's time goes: `vectorize {logo.name}`, one process:\n\n"
                  + profile(logo) + f"\n\nAnd a photo's, `vectorize {photo.name}`:\n\n" + profile(photo))
    print(text)
    if args.markdown:
        write_section(args.markdown, text)


if __name__ == "__main__":
    main()
