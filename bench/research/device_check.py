"""Does inference run on CUDA, and draw what it draws on the CPU? (run on a lent GPU machine)

For each shipped model given, on its 64 test-split assets (tests/assets/<set>_test) or the
first ``--images``: ``vectorize`` refined (the default), ``--no-refine``, ``--no-refine
--parts model`` and ``encode --fit``, on ``--device`` and on the CPU, then ``sample`` and
``interpolate`` (``--parts model``) on ``--device``. Prints, per mode, the seconds per
picture on each device and how alike the two results are: the IoU of their renders at 4x
(our renderer, on the CPU; the pixels that are not white), or the latents' relative
distance. A failure prints its one line (and traceback) and the check goes on.

    python bench/research/device_check.py --models DIR... --assets DIR... [--images 16] [--device cuda]

On the lent machine it reads what ``pack`` put in .gpu/ (bench/device_phases.py says how the
tree travels): ``python3 bench/research/device_check.py --pack``.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "src"))
PACK = ROOT / ".gpu" / "check"


def pack(sets: list[str], images: int) -> None:
    shutil.rmtree(PACK, ignore_errors=True)
    for name in sets:
        shutil.copytree(ROOT / "models" / name, PACK / "models" / name)
        (PACK / "assets" / name).mkdir(parents=True)
        for png in sorted((ROOT / "tests" / "assets" / f"{name}_test").glob("*.png"))[:images]:
            shutil.copy2(png, PACK / "assets" / name / png.name)


def _iou(a, b) -> float:
    from im2vec_cli.vector.tensors import render_vector

    ra, rb = ((render_vector(v, scale=4.0) < 0.95).any(0) for v in (a, b))  # not white, (H, W)
    union = (ra | rb).sum().item()
    return 1.0 if union == 0 else (ra & rb).sum().item() / union


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


MODES = ("vectorize", "no-refine", "no-refine-model", "encode-fit", "sample", "interpolate")


def _vectorize_fields(mode: str) -> dict:
    return {"vectorize": {}, "no-refine": {"refine": False}, "no-refine-model": {"refine": False, "parts": "model"}}[mode]


def _compare(mode: str, models: dict, pictures: list, device: str) -> str:
    """One mode on the CPU and on ``device``: seconds per picture each, and how alike the results are."""
    import torch

    from im2vec_cli import api

    out = {}
    for d, m in models.items():
        if mode == "encode-fit":
            run = lambda x, m=m: api.encode(x, m, fit=True)  # noqa: E731
        else:
            run = lambda x, m=m, f=_vectorize_fields(mode): api.vectorize(x, m, **f)  # noqa: E731
        run(pictures[:1])  # warm-up: first CUDA calls, lazy imports
        out[d] = _timed(lambda run=run: run(pictures))
    (a, ta), (b, tb) = out["cpu"], out[device]
    n = len(pictures)
    head = f"{mode}: {n} pictures, s/picture cpu {ta / n:.3f} {device} {tb / n:.3f}; "
    if mode == "encode-fit":
        a, b = torch.as_tensor(a), torch.as_tensor(b)
        rel = ((a - b).norm(dim=1) / a.norm(dim=1)).tolist()
        return head + f"latent |{device} - cpu| / |cpu| mean {sum(rel) / n:.4f} max {max(rel):.4f}"
    ious = [_iou(x, y) for x, y in zip(a, b)]
    return head + (f"IoU@4x {device} vs cpu mean {sum(ious) / n:.4f} min {min(ious):.4f}; segments cpu "
                   f"{sum(v.num_segments for v in a) / n:.1f} {device} {sum(v.num_segments for v in b) / n:.1f}")


def check(model_dir: Path, assets: list[Path], device: str, modes: list[str]):
    """Yields the report's lines as each mode ends (a command stopped at its limit keeps them)."""
    import torch
    from PIL import Image

    from im2vec_cli import api

    pictures = [Image.open(p).convert("RGBA") for p in assets]
    models = {d: api.load_model(str(model_dir), device=d) for d in ("cpu", device)}
    m = models[device]
    own = {"sample": lambda: api.sample(16, m, seed=0, parts="model"),
           "interpolate": lambda: api.interpolate(pictures[0], pictures[1], m, steps=4, parts="model")}
    for mode in modes:
        try:
            if mode in own:
                out, s = _timed(own[mode])
                line = (f"{mode} on {device} (--parts model): {len(out)} graphics in {s:.2f} s, "
                        f"{sum(len(v.shapes) for v in out)} shapes")
            else:
                line = _compare(mode, models, pictures, device)
        except Exception as e:  # noqa: BLE001  (a report: every mode is tried)
            traceback.print_exc()
            line = f"{mode}: FAILED {type(e).__name__}: {e}"
        yield f"{model_dir.name} {line}"
    if device.startswith("cuda"):
        yield f"{model_dir.name}: peak CUDA memory {torch.cuda.max_memory_allocated() / 2**20:.0f} MiB"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="*", type=Path, default=[])
    ap.add_argument("--assets", nargs="*", type=Path, default=[])
    ap.add_argument("--images", type=int, default=64)
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--modes", nargs="*", choices=MODES, default=list(MODES))
    ap.add_argument("--pack", action="store_true", help="Use .gpu/check (made here by --make-pack SET...).")
    ap.add_argument("--make-pack", nargs="*", metavar="SET", help="Copy these sets' models and assets to .gpu/check.")
    args = ap.parse_args()
    if args.make_pack:
        return pack(args.make_pack, args.images)
    if args.pack:
        args.models = sorted((PACK / "models").iterdir())
        args.assets = [PACK / "assets" / m.name for m in args.models]
    for model_dir, folder in zip(args.models, args.assets, strict=True):
        for line in check(model_dir, sorted(folder.glob("*.png"))[: args.images], args.device, args.modes):
            print(line, flush=True)


if __name__ == "__main__":
    main()
