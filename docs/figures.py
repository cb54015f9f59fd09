"""The published figures outside docs/RESULTS.md, written from the files RESULTS.md is written from.

One source per figure: ``docs/results/<set>.json``, ``<set>-fitted.json`` and ``<set>-ImageVAE.json``
(the `im2vec eval` runs of ``make results``) give every test-split figure; ``models/<set>/metrics.json``
(``bench/ship_phase.py``) the 64 test-asset figures and the training summary. From them this writes,
between ``<!-- figures:NAME:begin -->`` and ``<!-- figures:NAME:end -->`` markers:

- README.md: the models table (``models``) and the results summary (``results``);
- models/<set>/README.md: the card's "How good" block (``card``);
- docs/HOW-IT-WORKS.md: the figures its "What the figures say" argues from (``argument``).

    python docs/figures.py           # rewrite the marked blocks (``make results`` runs it too)
    python docs/figures.py --check   # list the stale ones, exit 1 if any (tests/test_figures.py)
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
SETS = ("fonts", "mnist", "emoji", "icons")
# The paper's Table 1 (reconstruction L2 on held-out images), as quoted in this project's issues
# (issue 26): arch -> dataset -> figure. Its datasets are not ours, so the like-for-like figure
# is the ratio Im2Vec / ImageVAE on the same data.
PAPER = {"im2vec": {"fonts": 0.0284, "mnist": 0.0036, "emoji": 0.0014, "icons": 0.0003},
         "imagevae": {"fonts": 0.0116, "mnist": 0.0033, "emoji": 0.0016, "icons": 0.0002}}
WHAT = {  # set -> (its data, what its paths are): the models table's short cells, typed once here
    "fonts": ("Debian fonts, 64²: 521 training families, a–z A–Z 0–9", "4 paths, one even-odd black shape"),
    "mnist": ("MNIST digits, 28² padded into 32²", "3 paths, one even-odd black shape"),
    "emoji": ("Twemoji, 64²", "8 coloured layers composited by depth"),
    "icons": ("Material Design Icons, 64²", "8 paths, one nonzero black shape"),
}


def fmt(res: dict, key: str, digits: int = 4) -> str:
    """``res[key] ± res[key_stderr]`` at ``digits`` decimals, or a dash where it was not measured."""
    if key not in res:
        return "–"
    return f"{res[key]:.{digits}f} ± {res[key + '_stderr']:.{digits}f}"


def result(name: str) -> dict:
    """docs/results/NAME.json (``{}`` when that eval was not run)."""
    path = RESULTS / f"{name}.json"
    return json.loads(path.read_text()) if path.is_file() else {}


def metrics(name: str) -> dict:
    """models/NAME/metrics.json (``{}`` when absent)."""
    path = ROOT / "models" / name / "metrics.json"
    return json.loads(path.read_text()) if path.is_file() else {}


def ratio(a: dict, b: dict, key: str = "recon_l2") -> str:
    return f"{a[key] / b[key]:.2f}" if key in a and key in b else "–"


def models_table() -> list[str]:
    """README's table of the shipped models: short cells, figures from the eval files."""
    L = ["| name | data | paths | size | test reconstruction L2 (× our ImageVAE) | card |", "|---|---|---|---|---|---|"]
    for s in SETS:
        r, vae = result(s), result(f"{s}-ImageVAE")
        size = (ROOT / "models" / s / "model.safetensors").stat().st_size / 1e6
        name = f"`{s}` (default)" if s == "fonts" else f"`{s}`"
        L.append(f"| {name} | {WHAT[s][0]} | {WHAT[s][1]} | {size:.1f} MB (fp16) | {fmt(r, 'recon_l2')} on "
                 f"{r.get('images', '?')} test images ({ratio(r, vae)}×) | [models/{s}/README.md](models/{s}/README.md) |")
    return L


def results_table() -> list[str]:
    """README's summary of docs/RESULTS.md's Table 1 and 2, every set."""
    L = ["| set | Im2Vec recon L2 | paper | fitted (`eval --fit`) | ImageVAE, same data | Im2Vec / ImageVAE (paper's) "
         "| generation L2 Im2Vec / ImageVAE | interpolation L2 Im2Vec / ImageVAE |", "|---|---|---|---|---|---|---|---|"]
    for s in SETS:
        r, fit, vae = result(s), result(f"{s}-fitted"), result(f"{s}-ImageVAE")
        paper = PAPER["im2vec"][s] / PAPER["imagevae"][s]
        inter = (f"{r['interpolation_l2']:.3f} / {vae['interpolation_l2']:.3f}"
                 if "interpolation_l2" in r and "interpolation_l2" in vae else "–")
        gen = (f"{r['generation_l2']:.3f} / {vae['generation_l2']:.3f}"
               if "generation_l2" in r and "generation_l2" in vae else "–")
        L.append(f"| {s} | {fmt(r, 'recon_l2')} | {PAPER['im2vec'][s]:.4f} | {fmt(fit, 'recon_l2')} | {fmt(vae, 'recon_l2')} "
                 f"| {ratio(r, vae)} ({paper:.2f}) | {gen} | {inter} |")
    return L


def card(s: str) -> list[str]:
    """A model card's "How good" block."""
    r, fit, vae, m = result(s), result(f"{s}-fitted"), result(f"{s}-ImageVAE"), metrics(s)
    L = ["| figure | this model | our ImageVAE, same images | paper (its data) |", "|---|---|---|---|",
         f"| test-split reconstruction L2, {r.get('images', '?')} images (`make results`) | {fmt(r, 'recon_l2')} "
         f"| {fmt(vae, 'recon_l2')} | {PAPER['im2vec'][s]:.4f} |",
         f"| the same, paths fitted to each image (`eval --fit`) | {fmt(fit, 'recon_l2')} | – | – |"]
    if "assets_subset_recon_l2" in m:
        L.append(f"| the {m['assets_subset_images']} test assets (`tests/assets/{s}_test`), amortised / fitted "
                 f"| {m['assets_subset_recon_l2']:.5f} / {m.get('assets_subset_fitted_recon_l2', float('nan')):.5f} | – | – |")
    if "outline_iou" in r:
        L.append(f"| outline IoU at 4× / Chamfer distance, px | {r['outline_iou']:.3f} / {r['chamfer_px']:.2f} | – | – |")
    if "paths" in r:
        L.append(f"| paths / segments per picture | {r['paths']:.2f} / {r['segments']:.1f} | raster | – |")
    if "generation_l2" in r:
        L.append(f"| samples: L2 to the nearest training picture ({r.get('generation_prior', '?')} prior) "
                 f"| {r['generation_l2']:.4f} | {vae['generation_l2']:.4f} | – |" if "generation_l2" in vae else
                 f"| samples: L2 to the nearest training picture | {r['generation_l2']:.4f} | – | – |")
    t = m.get("training", {})
    L += ["", f"Trained {t.get('steps', m.get('step', '?')):,} steps in all; hardware: {t.get('hardware', '?')}. "
          "Recon L2: MSE on [0, 1] pixels between the test picture and the cairosvg render of the SVG "
          "`vectorize --no-refine --parts model` writes (docs/RESULTS.md)."]
    return L


def argument() -> list[str]:
    """The figures docs/HOW-IT-WORKS.md's "What the figures say" argues from, one line a set."""
    L = []
    for s in SETS:
        r, fit, vae = result(s), result(f"{s}-fitted"), result(f"{s}-ImageVAE")
        paper = PAPER["im2vec"][s] / PAPER["imagevae"][s]
        L.append(f"- **{s}**: {fmt(r, 'recon_l2')} (paper {PAPER['im2vec'][s]:.4f}), {ratio(r, vae)}× our ImageVAE on "
                 f"the same {r.get('images', '?')} images (the paper's ratio {paper:.2f}); fitted to each picture "
                 f"{ratio(fit, vae)}×.")
    return L


def blocks() -> list[tuple[Path, str, list[str]]]:
    """Every marked block: (file, block name, its lines)."""
    out = [(ROOT / "README.md", "models", models_table()), (ROOT / "README.md", "results", results_table()),
           (ROOT / "docs" / "HOW-IT-WORKS.md", "argument", argument())]
    return out + [(ROOT / "models" / s / "README.md", "card", card(s)) for s in SETS]


def replaced(text: str, name: str, lines: list[str]) -> str:
    """``text`` with the block between NAME's markers replaced by ``lines`` (a ``KeyError`` if it has no markers)."""
    begin, end = f"<!-- figures:{name}:begin -->", f"<!-- figures:{name}:end -->"
    pattern = re.compile(re.escape(begin) + r"\n.*?" + re.escape(end), re.S)
    if not pattern.search(text):
        raise KeyError(f"no {begin} ... {end} block")
    return pattern.sub(lambda _: "\n".join([begin, *lines, end]), text, count=1)


def stale() -> list[str]:
    """The marked blocks whose text is not what the results files give, as ``file: block``."""
    bad = []
    for path, name, lines in blocks():
        text = path.read_text()
        if replaced(text, name, lines) != text:
            bad.append(f"{path.relative_to(ROOT)}: {name}")
    return bad


def write() -> None:
    """Rewrite every marked block from the results files."""
    for path, name, lines in blocks():
        path.write_text(replaced(path.read_text(), name, lines))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="List the stale blocks; exit 1 if any.")
    args = ap.parse_args()
    if args.check:
        bad = stale()
        print("\n".join(bad) or "every published figure is up to date", file=sys.stderr)
        return 1 if bad else 0
    write()
    return 0


if __name__ == "__main__":
    sys.exit(main())
