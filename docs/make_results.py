"""Regenerate docs/RESULTS.md (and docs/results/*) from the shipped models: `make results`.

Every figure comes from an `im2vec eval` command run here, as a user would run it; the
command, its wall time and the machine are written beside the figure. The paper's numbers
are the only typed-in figures (``figures.PAPER``), each with where it comes from. The tables are
written by docs/results_tables.py; README's and the cards' figures by docs/figures.py, from the same files.

    python docs/make_results.py --data data [--limit 500] [--sweep-limit 150] [--only fonts,mnist]

Datasets are the `im2vec data` folders under ``--data`` (`make data-fonts` etc.); a model
whose dataset is missing is listed as skipped, not silently dropped.
"""

from __future__ import annotations

import argparse
import json
import re
import shlex
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import figures
from results_tables import write_markdown

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "results"
EXE = [sys.executable, "-m", "im2vec_cli"]

# (label, model folder, dataset folder name); "<set> fitted": the model's paths fitted to each test image
# (`eval --fit`, what `interpolate` draws), reconstruction only
MODELS = [
    ("fonts", "models/fonts", "fonts"),
    ("fonts fitted", "models/fonts", "fonts"),
    ("fonts ImageVAE", "models/baselines/fonts-imagevae", "fonts"),
    ("mnist", "models/mnist", "mnist"),
    ("mnist fitted", "models/mnist", "mnist"),
    ("mnist ImageVAE", "models/baselines/mnist-imagevae", "mnist"),
    ("emoji", "models/emoji", "emoji"),
    ("emoji fitted", "models/emoji", "emoji"),
    ("emoji ImageVAE", "models/baselines/emoji-imagevae", "emoji"),
    ("icons", "models/icons", "icons"),
    ("icons fitted", "models/icons", "icons"),
    ("icons ImageVAE", "models/baselines/icons-imagevae", "icons"),
]
# Segments ablation (paper Fig. 5): (label, model folder, dataset, also deformation off at inference?)
SWEEPS = [
    ("fonts", "models/fonts", "fonts"),
    ("mnist, trained with deformation", "models/ablation/mnist-deform", "mnist"),
    ("mnist, trained without deformation", "models/ablation/mnist-nodeform", "mnist"),
]
def _command(name: str, args: list[str]) -> tuple[Path, list[str], str]:
    """The result file, the `im2vec eval` arguments and the command as shown for ``name``."""
    out = OUT / f"{name}.json"
    cmd = ["eval", *args, "-o", str(out.relative_to(ROOT))]
    return out, cmd, "im2vec " + " ".join(shlex.quote(a) for a in cmd)


def _earlier(name: str, args: list[str]) -> dict | None:
    """The result an earlier run of this command left in docs/results/, if any: the same command but
    for where its datasets were (``--data`` / ``--train-data`` folders compared by their last name)."""
    out, _, shown = _command(name, args)
    if out.is_file():
        res = json.loads(out.read_text())
        if _placed(res.get("command", "")) == _placed(shown):
            return res
    return None


def _placed(command: str) -> str:
    """``command`` with each dataset folder reduced to its name (``--data /work/data/fonts`` -> ``--data fonts``)."""
    return re.sub(r"(--(?:train-)?data) \S*?([^/\s]+)(?=\s|$)", r"\1 \2", command)


def run_eval(name: str, args: list[str], earlier: dict | None = None) -> dict:
    """Run `im2vec eval ARGS -o docs/results/NAME.json`; returns the JSON with the command
    and its wall time added, or ``earlier`` (``_earlier``'s result, kept with ``--reuse``)."""
    out, cmd, shown = _command(name, args)
    if earlier is not None:
        print(f"reused: {shown}", file=sys.stderr, flush=True)
        return {**earlier, "reused": True}
    print(f"$ {shown}", file=sys.stderr, flush=True)
    t = time.perf_counter()
    subprocess.run(EXE + cmd, cwd=ROOT, check=True)
    res = json.loads(out.read_text())
    res["command"], res["wall_s"] = shown, round(time.perf_counter() - t, 1)
    out.write_text(json.dumps(res, indent=1) + "\n")
    return res


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default="data", help="Folder of the `im2vec data` datasets.")
    ap.add_argument("--limit", type=int, default=500, help="Test images per model (seeded subset).")
    ap.add_argument("--sweep-limit", type=int, default=150, help="Test images per point of the ablation.")
    ap.add_argument("--samples", type=int, default=1000, help="Prior samples (generation).")
    ap.add_argument("--pairs", type=int, default=250, help="Training pairs (interpolation).")
    ap.add_argument("--only", default=None, help="Comma-separated dataset names to run (default: all).")
    ap.add_argument("--jobs", type=int, default=1, help="Evals run at once (each is one `im2vec eval` process).")
    ap.add_argument("--reuse", action="store_true",
                    help="Keep the figures already in docs/results/ (of an interrupted run) instead of rerunning "
                         "them; their datasets need not be present.")
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    results, samples, sweeps, skipped = {}, {}, {}, []
    todo = plan(args, results, samples, sweeps, skipped)
    if not any(table is results for table, *_ in todo):
        sys.exit(f"make_results: no eval to run or reuse (datasets under {args.data}? {'; '.join(skipped)})")
    with ThreadPoolExecutor(max(1, args.jobs)) as pool:  # threads: each eval is its own process
        done = list(pool.map(lambda t: run_eval(*t[3:]), todo))
    for (table, label, model, *_), res in zip(todo, done):
        table[label] = {**res, "model_dir": model}
    if any(label.startswith("mnist") for label in sweeps):
        from im2vec_cli.evaluate import sweep_plot

        series = {label.replace("mnist, ", ""): r["segments_sweep"] for label, r in sweeps.items()
                  if label.startswith("mnist")}
        (OUT / "sweep-mnist.png").write_bytes(sweep_plot(series, "MNIST: deformation in training vs not"))
    every = [*results.values(), *samples.values(), *sweeps.values()]
    evals_s = sum(r["wall_s"] for r in every)
    reused = sum(bool(r.get("reused")) for r in every)
    write_markdown(results, sweeps, skipped, args, evals_s, reused, samples)
    figures.write()  # README's tables, the cards' figures and HOW-IT-WORKS's, from the same files


def plan(args, results: dict, samples: dict, sweeps: dict, skipped: list) -> list[tuple]:
    """The evals to run (or reuse), each ``(table, label, model, name, args, earlier)``; what cannot be
    run here (its model or dataset missing) is added to ``skipped``."""
    data = Path(args.data).absolute()  # not resolved: a symlinked data folder keeps its name in the commands
    only = set(args.only.split(",")) if args.only else None
    todo = []
    for label, model, ds in MODELS:
        if only and ds not in only:
            continue
        extra = ["--fit"] if label.endswith("fitted") else [
            "--train-data", str(data / ds), "--samples", str(args.samples), "--pairs", str(args.pairs)]
        cmd = ["--model", model, "--data", str(data / ds), "--limit", str(args.limit), *extra]
        todo += _one(results, label, model, label.replace(" ", "-"), cmd, data / ds, args.reuse, skipped, label)
        if not label.endswith("fitted") and (ROOT / "models" / "features" / ds / "config.json").is_file():
            # sample quality: its own eval (the reconstruction figure of its few --limit images is not used)
            cmd = ["--model", model, "--data", str(data / ds), "--limit", "20", "--features", f"models/features/{ds}",
                   "--samples", str(args.samples)]
            todo += _one(samples, label, model, "samples-" + label.replace(" ", "-"), cmd, data / ds, args.reuse)
    for label, model, ds in SWEEPS:
        if only and ds not in only:
            continue
        name = "sweep-" + Path(model).name
        cmd = ["--model", model, "--data", str(data / ds), "--limit", str(args.sweep_limit), "--sweep", "6-25",
               "--plot", str((OUT / f"{name}.png").relative_to(ROOT))]
        todo += _one(sweeps, label, model, name, cmd, data / ds, args.reuse, skipped, f"ablation: {label}")
    return todo


def _one(table, label, model, name, cmd, data: Path, reuse: bool, skipped: list | None = None, shown: str = ""):
    """``[the eval to run]``, or ``[]`` (named in ``skipped`` when given) when it cannot run here."""
    earlier = _earlier(name, cmd) if reuse else None
    if (ROOT / model / "config.json").is_file() and (data.is_dir() or earlier):
        return [(table, label, model, name, cmd, earlier)]
    if skipped is not None:
        skipped.append(f"{shown} ({model} or {data} missing)")
    return []


if __name__ == "__main__":
    main()
