"""Interpolations you would show (issue 36): faithful end frames, clean frames throughout.

The set, built from packages no shipped model trained on: 12 characters, each in two faces of
GNU FreeFont and Lato (Debian fonts-freefont-ttf, fonts-lato; bench/outlines.py checks neither
package is in shared/data/font-packages.txt), rendered at 64 px as the Fonts dataset does,
with the true outline from fontTools. Each pair is interpolated with ``--steps 6`` (8 frames),
and two different letters besides.

Per run: end frames IoU@4x against the true outlines; the share of all frames with the
character's pieces and holes (those of either end, each of at least one input pixel, at 4x);
the share of frames that render the same under even-odd and nonzero; the jump (the largest
change between two neighbouring frames over their mean: 1 is an even morph, 7 all of it in one
step); seconds per pair. Then 32 fonts samples (fitted prior): pieces + holes per sample, and
MNIST's.

    python bench/morphs.py [--markdown F] [--sheet PNG]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

from im2vec_cli import api  # noqa: E402
from im2vec_cli.data.fonts import render_png  # noqa: E402
from im2vec_cli.data.glyphs import glyph_image  # noqa: E402
from im2vec_cli.files import load_image  # noqa: E402
from im2vec_cli.vector import rasterize_svg, to_svg  # noqa: E402
from outlines import FACES, SIZE, UP, _ink, _topology, held_out_fonts  # noqa: E402

CHARS = "aegRB8kQdsx4"
STEPS = 6


def pairs() -> list[dict]:
    """12 pairs: character ``CHARS[i]`` in faces ``i`` and ``i + 5`` of ``FACES`` (mod 10)."""
    fonts = dict(held_out_fonts(lambda face: face in FACES))
    faces = [f for f in FACES if f in fonts]
    out = []
    for i, c in enumerate(CHARS):
        ends = []
        for face in (faces[i % len(faces)], faces[(i + len(faces) // 2) % len(faces)]):
            svg = to_svg(glyph_image(fonts[face], c, size=SIZE, margin=4.0), decimals=3)
            ends.append({"name": f"{face[0]}-{face[1]}-{c}", "png": render_png(svg, SIZE),
                         "truth": rasterize_svg(svg, SIZE * UP, SIZE * UP)})
        out.append({"char": c, "ends": ends})
    return out


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max((a | b).sum(), 1))


def rule_agrees(svg: str) -> bool:
    """The SVG renders the same (at 4x, within antialiasing) under even-odd and nonzero."""
    even = rasterize_svg(svg.replace('fill-rule="nonzero"', 'fill-rule="evenodd"'), SIZE * UP, SIZE * UP)
    non = rasterize_svg(svg.replace('fill-rule="evenodd"', 'fill-rule="nonzero"'), SIZE * UP, SIZE * UP)
    return bool((np.abs(even - non).max(-1) > 0.5).sum() <= 2 * UP)


def jump(masks: list[np.ndarray]) -> float:
    """The largest change between neighbouring frames over the mean change (1: even)."""
    d = np.array([(a ^ b).mean() for a, b in zip(masks, masks[1:])])
    return float(d.max() / max(d.mean(), 1e-9))


def score_pair(p: dict, svgs: list[str]) -> dict:
    masks = [_ink(rasterize_svg(s, SIZE * UP, SIZE * UP)) for s in svgs]
    truths = [_ink(e["truth"]) for e in p["ends"]]
    want = {_topology(t) for t in truths}
    return {"end_iou": [iou(masks[0], truths[0]), iou(masks[-1], truths[1])],
            "topology": [_topology(m) in want for m in masks], "rule": [rule_agrees(s) for s in svgs],
            "jump": jump(masks)}


def run_api(p: dict, model, **kw) -> list[str]:
    a, b = (load_image(e["name"] + ".png", e["png"]) for e in p["ends"])
    return [v.to_svg() for v in api.interpolate(a, b, model, steps=STEPS, **kw)]


def run_latent_walk(p: dict, model) -> list[str]:
    """The alternative to interpolating the fitted paths: frames decoded from the interpolated
    fitted latents, plus the interpolated residuals (fitted paths minus the latent's), so the
    ends are the same fitted projections."""
    import torch

    from im2vec_cli.model.vae import Decoded
    from im2vec_cli.project import Projection, from_latents, project

    ims = [load_image(e["name"] + ".png", e["png"]) for e in p["ends"]]
    proj = project(model, ims)
    rest = proj.decoded.points - from_latents(model, proj.z).decoded.points  # (2, P, 3k, 2)
    t = torch.linspace(0, 1, STEPS + 2).view(-1, 1)
    walk = from_latents(model, proj.z[:1] * (1 - t) + proj.z[1:] * t)
    w = t.view(-1, 1, 1, 1)
    d = walk.decoded
    frames = Projection(walk.z, Decoded(d.points + rest[:1] * (1 - w) + rest[1:] * w, d.colors, d.depth,
                                        d.shape_index, d.fill_rule))
    return [v.to_svg() for v in frames.vectors(model.config.image_size)]


def cli_seconds(p: dict, repeat: int = 3) -> float:
    """Median wall time of ``im2vec interpolate A B --steps 4`` (a new process, start included)."""
    import statistics
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        a, b = Path(tmp, "a.png"), Path(tmp, "b.png")
        a.write_bytes(p["ends"][0]["png"])
        b.write_bytes(p["ends"][1]["png"])
        times = []
        for i in range(repeat):
            t = time.perf_counter()
            subprocess.run([sys.executable, "-m", "im2vec_cli", "interpolate", str(a), str(b), "--steps", "4",
                            "-o", str(Path(tmp, f"out{i}"))], check=True, capture_output=True)
            times.append(time.perf_counter() - t)
    return statistics.median(times)


CELL = 96


def sheet(pairs_svgs: list[tuple[dict, list[str]]], path: str) -> None:
    """One row a pair: input A | the frames (cairosvg renders of the SVGs) | input B."""
    from PIL import Image

    n = max(len(s) for _, s in pairs_svgs) + 2
    out = Image.new("RGB", (n * CELL, len(pairs_svgs) * CELL), "white")
    for r, (p, svgs) in enumerate(pairs_svgs):
        cells = [p["ends"][0]["png"], *svgs, p["ends"][1]["png"]]
        for c, item in enumerate(cells):
            if isinstance(item, bytes):
                img = load_image("x.png", item)
                arr = img.permute(1, 2, 0).numpy()
                im = Image.fromarray(np.round(arr * 255).astype(np.uint8)).resize((CELL, CELL), Image.NEAREST)
            else:
                im = Image.fromarray(np.round(rasterize_svg(item, CELL, CELL) * 255).astype(np.uint8))
            out.paste(im, (c * CELL, r * CELL))
    out.save(path)


def summary(rows: list[dict]) -> dict:
    return {"end_iou": float(np.mean([x for r in rows for x in r["end_iou"]])),
            "topology": float(np.mean([x for r in rows for x in r["topology"]])),
            "rule": float(np.mean([x for r in rows for x in r["rule"]])),
            "jump_max": float(np.max([r["jump"] for r in rows])), "jump_mean": float(np.mean([r["jump"] for r in rows])),
            "s_per_pair": float(np.mean([r["s"] for r in rows]))}


def sample_topology(model_name: str, n: int = 32, seed: int = 0, parts: str = "clean") -> float:
    """Mean pieces + holes of ``n`` samples (fitted prior, ``seed``), each at least one input px at 4x."""
    model = api.load_model(model_name, "cpu")
    svgs = [v.to_svg() for v in api.sample(n, model, seed=seed, parts=parts)]
    return float(np.mean([sum(_topology(_ink(rasterize_svg(s, SIZE * UP, SIZE * UP)))) for s in svgs]))


def data_topology(folder: Path) -> float:
    """The same count on real images (``folder``'s pictures, upscaled 4x bilinear, ink below 0.5)."""
    import torch.nn.functional as F

    from im2vec_cli.data.folder import list_images

    counts = []
    for f in list_images(folder):
        im = load_image(f)
        big = F.interpolate(im[None], size=(SIZE * UP, SIZE * UP), mode="bilinear")[0]
        counts.append(sum(_topology(big.mean(0).numpy() < 0.5)))
    return float(np.mean(counts))


DIFFERENT = [(0, 0, 3, 1), (1, 0, 2, 1), (6, 0, 5, 1)]  # (pair, end, pair, end): a -> R, e -> g, k -> 8


def run(name: str, sets: list[dict], model, walk: bool = False, **kw) -> tuple[dict, list]:
    rows, shown = [], []
    for p in sets:
        t = time.perf_counter()
        svgs = run_latent_walk(p, model) if walk else run_api(p, model, **kw)
        r = score_pair(p, svgs)
        r["s"] = time.perf_counter() - t
        rows.append(r)
        shown.append((p, svgs))
    out = summary(rows)
    print(f"{name:34s} end IoU@4x {out['end_iou']:.4f}  topology {out['topology']:.1%}  even-odd = nonzero "
          f"{out['rule']:.1%}  jump max {out['jump_max']:.2f} (mean {out['jump_mean']:.2f})  {out['s_per_pair']:.2f} s",
          flush=True)
    return out, shown


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--markdown", default=None)
    ap.add_argument("--sheet", default=None, help="write a contact sheet of every pair's frames (fitted)")
    ap.add_argument("--samples", type=int, default=128)
    args = ap.parse_args()
    model = api.load_model("fonts", "cpu")
    sets = pairs()
    others = [{"char": sets[i]["char"] + sets[j]["char"], "ends": [sets[i]["ends"][a], sets[j]["ends"][b]]}
              for i, a, j, b in DIFFERENT]
    run_api(sets[0], model)  # warm-up
    res = {"guess (--no-fit)": run("encoder's guess (--no-fit)", sets, model, fit=False)[0]}
    res["fitted (default)"], shown = run("fitted (default)", sets, model)
    res["fitted, model's paths"] = run("fitted, --parts model", sets, model, parts="model")[0]
    res["fitted, frames through the latent"] = run("fitted, frames through the latent", sets, model, walk=True)[0]
    res["different letters, fitted"], diff = run("different letters, fitted", others, model)
    wall = cli_seconds(sets[0])
    print(f"im2vec interpolate A B --steps 4: {wall:.2f} s wall (process start included)", flush=True)
    samples = {}
    for name, folder in (("fonts", "fonts_test"), ("mnist", "mnist_test")):
        samples[name] = {"clean": sample_topology(name, args.samples), "model": sample_topology(name, args.samples, parts="model"),
                         "n32": sample_topology(name, 32), "data": data_topology(ROOT / "tests" / "assets" / folder)}
        print(f"samples {name}: pieces + holes {samples[name]['clean']:.2f} (32 samples, seed 0: {samples[name]['n32']:.2f}; "
              f"model's paths {samples[name]['model']:.2f}; test images {samples[name]['data']:.2f})", flush=True)
    if args.sheet:
        sheet(shown + diff, args.sheet)
    if args.markdown:
        Path(args.markdown).write_text(markdown(res, wall, samples, args.samples))


def markdown(res: dict, wall: float, samples: dict, n: int) -> str:
    lines = [f"# Interpolations on held-out glyphs\n\nWritten by `make bench-morphs` "
             f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} CPU cores); the set and the "
             "figures are described in bench/morphs.py. Model `fonts`, 12 pairs of one character in two faces of "
             f"GNU FreeFont and Lato (neither trained on), `--steps {STEPS}`.\n",
             "| frames | end frames IoU@4x | frames with the character's pieces and holes | even-odd = nonzero | "
             "largest jump / mean step | s / pair |", "|---|---|---|---|---|---|"]
    for name, r in res.items():
        lines.append(f"| {name} | {r['end_iou']:.4f} | {r['topology']:.1%} | {r['rule']:.1%} | {r['jump_max']:.2f} | "
                     f"{r['s_per_pair']:.2f} |")
    lines += ["", "(\"different letters\": a -> R, e -> g, k -> 8; a frame counts when it has the pieces and holes of "
              "either end.)", "", f"`im2vec interpolate A B --steps 4` on two 64 px glyphs: **{wall:.2f} s** wall, "
              "process start included (median of 3).", "",
              f"Samples ({n}, and 32 on their own; fitted prior, seed 0): pieces + holes per sample, each of at least one input pixel.", "",
              "| model | clean (default) | clean, 32 samples | the model's paths | test images |", "|---|---|---|---|---|"]
    for name, r in samples.items():
        lines.append(f"| {name} | {r['clean']:.2f} | {r['n32']:.2f} | {r['model']:.2f} | {r['data']:.2f} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
