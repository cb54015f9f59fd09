"""What makes the fonts vector model several times the raster baseline's error? (issue 26, part 3)

Every row scores the same test glyphs by the paper's Table 1 figure (MSE on [0, 1] pixels of
the cairosvg render of the SVG against the input), one factor at a time, from the shipped
``fonts`` model:

- *amortised*: ``z = mu`` decoded at k = 12 (what ``vectorize --no-refine --parts model`` writes) and at k = 25;
- *z optimised*: the latent fitted to each glyph (Adam through our renderer): the amortisation
  gap of the encoder;
- *path codes optimised*: the LSTM's per-path codes fitted directly (the path decoder kept): what
  the decoder can draw with its P paths when the latent is not the bottleneck;
- *points optimised*: the control points themselves fitted (P paths of k segments, even-odd),
  from the amortised start: the bound of the representation at that P and k;
- the ImageVAE baseline on the same glyphs, for the ratio.

Also the MSE that the training loss sees (our soft render at the training tau) beside the
cairosvg one, for the soft edge. Prints a Markdown table; ``--markdown FILE`` writes it too.

    python bench/research/fonts_ablation.py [--images tests/assets/fonts_test] [--steps 150]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from im2vec_cli.data.folder import list_images
from im2vec_cli.files import load_image
from im2vec_cli.infer import model_input, to_vector
from im2vec_cli.model.pretrained import from_pretrained
from im2vec_cli.model.vae import Decoded
from im2vec_cli.raster.bezier import subdivide_to
from im2vec_cli.vector import rasterize_svg, to_svg

ROOT = Path(__file__).resolve().parents[2]


def svg_mse(model, dec: Decoded, images: torch.Tensor, places) -> list[float]:
    """Per-image MSE of the cairosvg render of what ``to_vector`` writes, ``images (B, 3, S, S)``."""
    out = []
    for i, place in enumerate(places):
        vec = to_vector(dec, i, place)
        h, w = images.shape[2:]
        arr = torch.from_numpy(rasterize_svg(to_svg(vec, 3), w, h)).permute(2, 0, 1).float()
        out.append(float(((arr - images[i]) ** 2).mean()))
    return out


def soft_mse(model, dec: Decoded, x: torch.Tensor, tau: float) -> float:
    with torch.no_grad():
        return float(((model.render(dec, tau=tau, composite="soft") - x) ** 2).mean())


def fit(model, x: torch.Tensor, params: list[torch.Tensor], make_dec, steps: int, lr: float) -> Decoded:
    """Adam on ``params`` to the MSE of a 2x2-supersampled render (tau 0.3 px) against ``x``."""
    opt = torch.optim.Adam(params, lr=lr)
    for _ in range(steps):
        dec = make_dec()
        loss = ((model.render(dec, tau=0.3, composite="over", supersample=2) - x) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    with torch.no_grad():
        return make_dec()


def decode_codes(model, code: torch.Tensor, k: int, like: Decoded) -> Decoded:
    """Per-path codes ``(B, P, C)`` -> ``Decoded`` with the model's path decoder (the LSTM skipped)."""
    return Decoded(model.path_points(code, k), like.colors, like.depth, like.shape_index, like.fill_rule)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="fonts")
    ap.add_argument("--baseline", default=str(ROOT / "models" / "baselines" / "fonts-imagevae"))
    ap.add_argument("--images", default=str(ROOT / "tests" / "assets" / "fonts_test"))
    ap.add_argument("--steps", type=int, default=150, help="Adam steps of each optimised row")
    ap.add_argument("--limit", type=int, default=None, help="the first N images only (a quick check)")
    ap.add_argument("--more", action="store_true", help="also the points rows at k = 24 and under nonzero")
    ap.add_argument("--markdown", default=None)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    torch.manual_seed(0)
    model, files, x, places, target = setup(args.model, args.images, args.limit)
    rows = []

    def row(name, dec, t0, note=""):
        errs = svg_mse(model, dec, target, places)
        rows.append({"row": name, "recon_l2": float(np.mean(errs)), "stderr": float(np.std(errs) / np.sqrt(len(errs))),
                     "soft_mse": soft_mse(model, dec, x, 0.3), "seconds": time.perf_counter() - t0, "note": note})
        print(json.dumps(rows[-1]), flush=True)

    with torch.no_grad():
        mu, _ = model.encode(x)
    for k in (12, 25):
        t0 = time.perf_counter()
        with torch.no_grad():
            dec = model.decode(mu, k)
        row(f"amortised, k = {k}", dec, t0, "vectorize --no-refine --parts model")
    base = model.decode(mu, 12)

    t0 = time.perf_counter()
    z = mu.clone().requires_grad_(True)
    row("z optimised, k = 12", fit(model, x, [z], lambda: model.decode(z, 12), args.steps, 0.02), t0,
        "the encoder's amortisation gap")

    t0 = time.perf_counter()
    with torch.no_grad():
        code0 = model.codes(mu)[0]  # (B, P, C)
    code = code0.clone().requires_grad_(True)
    row("path codes optimised, k = 12", fit(model, x, [code], lambda: decode_codes(model, code, 12, base),
                                            args.steps, 0.02), t0, "the LSTM bypassed, the path decoder kept")

    def points_row(start: torch.Tensor, rule: str, note: str):
        t0 = time.perf_counter()
        logit = torch.logit(start.clamp(1e-4, 1 - 1e-4)).requires_grad_(True)  # (B, P, 3k, 2)
        mk = lambda: Decoded(torch.sigmoid(logit), base.colors, base.depth, base.shape_index, rule)  # noqa: E731
        k = start.shape[2] // 3
        row(f"points optimised, P = {start.shape[1]}, k = {k}, {rule}", fit(model, x, [logit], mk, args.steps, 0.05),
            t0, note)

    pts = base.points.detach()  # (B, P, 36, 2)
    points_row(pts, base.fill_rule, "the representation's bound at this P and k")
    if args.more:
        finer = torch.stack([torch.stack([subdivide_to(c, 24) for c in img]) for img in pts])  # (B, P, 72, 2)
        points_row(finer, base.fill_rule, "twice the segments")
        points_row(pts, "nonzero", "overlaps filled instead of cut")

    if args.baseline and Path(args.baseline).is_dir():
        rows.append(baseline_row(args.baseline, x))
    write(rows, args, len(files))


def baseline_row(folder: str, x: torch.Tensor) -> dict:
    """The ImageVAE's row: its raster output's MSE on the model inputs ``x (B, 3, S, S)``."""
    ivae = from_pretrained(folder).float().eval()
    with torch.no_grad():
        rec = ivae.decode(ivae.encode(x)[0]).clamp(0, 1)
    errs = ((rec - x) ** 2).mean(dim=(1, 2, 3))
    return {"row": "ImageVAE baseline (raster)", "recon_l2": float(errs.mean()),
            "stderr": float(errs.std() / np.sqrt(len(errs))), "soft_mse": float("nan"), "seconds": 0.0,
            "note": "its raster output"}


def write(rows: list[dict], args, n: int) -> None:
    """The table printed, and written to ``--markdown`` / ``--json`` when given."""
    where = Path(args.images).resolve()
    where = where.relative_to(ROOT) if where.is_relative_to(ROOT) else where
    text = table(rows, f"{n} glyphs from {where}; model {args.model}; {args.steps} Adam steps per optimised row.")
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(text)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1) + "\n")


def setup(name: str, images: str, limit: int | None):
    """The model, frozen, and the glyphs: (model, files, model inputs ``(B, 3, S, S)``, their places,
    the pictures at their own size ``(B, 3, H, W)``)."""
    model = from_pretrained(name).float().eval()
    for p in model.parameters():
        p.requires_grad_(False)
    files = list_images(images)[:limit]
    imgs = [load_image(f) for f in files]
    pairs = [model_input(model, im) for im in imgs]
    return model, files, torch.stack([p[0] for p in pairs]), [p[1] for p in pairs], torch.stack(imgs)


def table(rows: list[dict], head: str) -> str:
    """Markdown of the rows, each against the ImageVAE row (when there is one)."""
    ref = next((r["recon_l2"] for r in rows if r["row"].startswith("ImageVAE")), None)
    lines = [head, "", "| row | recon L2 (cairosvg) | x ImageVAE | MSE of the training render (soft, tau 0.3) | s | "
             "what it tells |", "|---|---|---|---|---|---|"]
    for r in rows:
        ratio = f"{r['recon_l2'] / ref:.1f}" if ref else "–"
        soft = "–" if np.isnan(r["soft_mse"]) else f"{r['soft_mse']:.4f}"
        lines.append(f"| {r['row']} | {r['recon_l2']:.4f} ± {r['stderr']:.4f} | {ratio} | {soft} | "
                     f"{r['seconds']:.0f} | {r['note']} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
