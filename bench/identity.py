"""Outputs byte for byte across a refactor (issue 67): a digest of every SVG ``vectorize`` writes.

Pictures: the examples (examples/*.png, each with its matching model), and a spread of the outline
benchmark's three held-out sets (bench/outlines.py: FreeFont/Lato glyphs with the fonts model, Font
Awesome icons with the icons model, OpenMoji faces with the emoji model; ``make bench-sets``), at
``--limit`` pictures a set. Each picture under each option set of ``OPTIONS`` (the CLI's main modes:
the defaults, each effort, a tolerance, a palette size, a preset, the model's own paths, without
refinement), one process, one thread, so the digests are deterministic.

    python bench/identity.py --save /tmp/before.json      # on the commit before
    python bench/identity.py --check /tmp/before.json     # after: lists every SVG that differs
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

OPTIONS = {  # name -> VectorizeOptions fields
    "defaults": {},
    "draft": {"effort": "draft"},
    "best": {"effort": "best"},
    "tolerance 1": {"tolerance": 1.0},
    "colors 3": {"colors": 3},
    "preset logo": {"preset": "logo"},
    "parts model": {"parts": "model"},
    "no-refine": {"refine": False},
    "no-refine, parts model": {"refine": False, "parts": "model"},
}
EXAMPLE_MODELS = {"digit": "mnist", "emoji": "emoji", "glyph": "fonts", "icon": "icons"}


def pictures(src: Path, limit: int) -> list[tuple[str, str, bytes]]:
    """``(name, model, PNG bytes)`` of every picture."""
    from outlines import _with_png, emoji, glyphs, icons

    out = [(f.stem, EXAMPLE_MODELS[f.stem.split("_")[0]], f.read_bytes()) for f in sorted((ROOT / "examples").glob("*.png"))]
    for name, rows, model, gray in (("glyphs", glyphs(limit), "fonts", True), ("icons", icons(src, limit), "icons", False),
                                    ("emoji", emoji(src, limit), "emoji", False)):
        out += [(f"{name}/{r['name']}", model, r["png"]) for r in _with_png(rows, gray)]
    return out


def digests(src: Path, limit: int) -> dict[str, str]:
    """``"picture | options" -> sha256 of its SVG``, or of the error it raised."""
    import torch

    from im2vec_cli import api
    from im2vec_cli.files import load_image

    torch.set_num_threads(1)
    models, out = {}, {}
    for name, model, png in pictures(src, limit):
        if model not in models:
            models[model] = api.load_model(model, "cpu")
        for opt, fields in OPTIONS.items():
            try:
                text = api.vectorize(load_image(name + ".png", png), models[model], **fields).to_svg()
            except Exception as e:  # noqa: BLE001 - a refactor must keep the errors too
                text = f"error: {type(e).__name__}: {e}"
            out[f"{name} | {opt}"] = hashlib.sha256(text.encode()).hexdigest()
        print(name, flush=True)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--src", type=Path, default=ROOT / "bench" / ".sets")
    ap.add_argument("--limit", type=int, default=12, help="pictures of each outline set")
    ap.add_argument("--save", type=Path, help="write the digests to this JSON file")
    ap.add_argument("--check", type=Path, help="compare with the digests in this JSON file")
    args = ap.parse_args()
    got = digests(args.src, args.limit)
    if args.save:
        args.save.write_text(json.dumps(got, indent=1) + "\n")
    if args.check:
        want = json.loads(args.check.read_text())
        differ = sorted(k for k in want.keys() | got.keys() if want.get(k) != got.get(k))
        print("\n".join(differ) or "none differ", file=sys.stderr)
        print(f"{len(got) - len(differ)} of {len(got)} SVGs byte-identical", file=sys.stderr)
        return 1 if differ else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
