"""Ship a training phase into models/<set> when it beats the shipped model (issue 37).

A phase (``make train-<set>``) fine-tunes the shipped model for at most ``--minutes``; this
script then exports the run's checkpoint as the shipped model is stored (fp16 when it is),
measures it and the shipped model on the same images:

- the test split (a seeded subset of ``--limit`` images of DATA/<set>/test): reconstruction L2
  of the SVG ``vectorize --no-refine --parts model`` writes, and the outline figures where the set has them;
- the 64 images of tests/assets/<set>_test (the figure ``tests/model/test_shipped_models.py``
  checks), amortised and fitted (``eval --fit``);

and ships the phase only when its test-split L2 is lower by ``--margin`` (1%) at least: the model files replace those in
models/<set>; metrics.json takes the new figures (the replaced ones kept under
``before_phase_<n>``) and a ``phases`` entry; docs/results/history-<set>.md gets a section with the command, the
config, the code commit and the validation curve, and the card's figures are rewritten (docs/figures.py). Commit models/<set> afterwards.

A RUN trained on a lent GPU machine (``bench/device_phases.py``) holds no checkpoint.pt: its
fp16 export came back in RUN/exported (with export.json, its step), and is measured as it is.

``--feedback N`` in place of RUN measures a phase without training: the shipped model with
N render-and-compare passes (``ModelConfig.feedback``; the weights are the same, its one
``Feedback`` module applied N times), its latent prior refitted with its own settings to the
latents those passes give. It ships by the same rule. ``--select`` adds
``ModelConfig.feedback_select``: per picture, the guess (the encoder's or a pass's) whose render
is closest to it.

    python bench/ship_phase.py RUN --set fonts --data DATA [--limit 1000] [--commit SHA] [--dry-run]
    python bench/ship_phase.py --feedback 3 --set icons --data DATA
    python bench/ship_phase.py --feedback 8 --select --set fonts --data DATA

``--path-passes N`` runs the phase's model (or, with no RUN and no ``--feedback``, the shipped
one, no training) with N passes of its path pass (``ModelConfig.path_passes``, ``PathPass``); the
latents stay, and so do the priors.

    python bench/ship_phase.py RUN --path-passes 2 --set emoji --data DATA
    python bench/ship_phase.py --path-passes 3 --set emoji --data DATA

``--point-passes N`` (with a RUN or alone, as ``--path-passes``) runs the model with N passes of
its point pass (``ModelConfig.point_passes``, ``model.points.PointPass``).

``--solve-colors`` (with a RUN or alone, as ``--path-passes``) sets ``ModelConfig.solve_colors``: the
layers' colours solved per picture by least squares once the shapes are drawn (a learned-colour
``layers`` model); the latents and priors stay.

    python bench/ship_phase.py --path-passes 4 --solve-colors --set emoji --data DATA

``--raw`` ships a run's trained weights rather than their EMA, for a run too short for the
average to catch up (its validation's ``raw_val_*`` figures say which is closer).

``--solve-order`` (implies ``--solve-colors``) sets ``ModelConfig.solve_order`` too: before the
colours, the layers' order is searched per picture by its solved render's error.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "docs"))
sys.path.insert(0, str(ROOT / "bench"))

import figures  # noqa: E402 - docs/figures.py

from im2vec_cli.config import DEFAULT_NEIGHBOURS, MAX_FEEDBACK  # noqa: E402
from im2vec_cli.evaluate import eval_files, reconstruction_l2  # noqa: E402
from im2vec_cli.files import atomic_write, replace_folder  # noqa: E402
from im2vec_cli.model.pretrained import export_checkpoint, from_pretrained, stored_half  # noqa: E402
from im2vec_cli.model.prior import NEIGHBOURS_CONFIG, NEIGHBOURS_WEIGHTS, PRIOR_CONFIG, PRIOR_WEIGHTS  # noqa: E402
from phase_card import _minutes, _started, card_section, phase_span, training_with  # noqa: E402

MODEL_FILES = ("config.json", "model.safetensors", PRIOR_CONFIG, PRIOR_WEIGHTS,
               NEIGHBOURS_CONFIG, NEIGHBOURS_WEIGHTS)  # a phase's own: never kept from the shipped


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", nargs="?", help="The phase's run folder (none with --feedback).")
    ap.add_argument("--feedback", type=int, choices=range(1, MAX_FEEDBACK + 1), metavar="N",
                    help="No run: the shipped model with this many feedback passes, its prior refitted.")
    ap.add_argument("--select", action="store_true",
                    help="With --feedback: keep per picture the pass whose render is closest (feedback_select).")
    ap.add_argument("--path-passes", type=int, choices=range(1, MAX_FEEDBACK + 1), metavar="N",
                    help="Run the phase's (no RUN: the shipped) model with this many path passes.")
    ap.add_argument("--point-passes", type=int, choices=range(1, MAX_FEEDBACK + 1), metavar="N",
                    help="Run the phase's (no RUN: the shipped) model with this many point passes.")
    ap.add_argument("--solve-colors", action="store_true",
                    help="Solve the layers' colours per picture (ModelConfig.solve_colors), with RUN or alone.")
    ap.add_argument("--solve-order", action="store_true",
                    help="Search the layers' order per picture too (ModelConfig.solve_order; implies --solve-colors).")
    ap.add_argument("--raw", action="store_true",
                    help="Export the run's trained weights, not its EMA (a short run whose average lags).")
    ap.add_argument("--set", required=True, dest="name")
    ap.add_argument("--data", required=True)
    ap.add_argument("--limit", type=int, default=1000)
    ap.add_argument("--margin", type=float, default=0.01, help="Relative improvement a phase must make to ship.")
    ap.add_argument("--commit", default=None,
                    help="The code commit the run trained at, for the card (default: the checkout's now).")
    ap.add_argument("--dry-run", action="store_true", help="Measure and tell; change nothing.")
    args = ap.parse_args()
    args.solve_colors = args.solve_colors or args.solve_order
    if args.run is not None and args.feedback is not None or args.run is None and not (
            args.feedback or args.path_passes or args.point_passes or args.solve_colors):
        ap.error("give either a RUN folder or --feedback N (or --path-passes N, --point-passes N or --solve-colors alone)")
    if args.select and args.feedback is None:
        ap.error("--select goes with --feedback N")
    shipped = ROOT / "models" / args.name
    run = Path(args.run) if args.run else None
    scratch, step, exported = candidate(args, shipped, run)
    if args.path_passes:
        with_path_passes(scratch, args.path_passes)
    if args.point_passes:
        with_path_passes(scratch, args.point_passes, "point")
    if args.solve_colors:
        with_config(scratch, solve_colors=True, solve_order=args.solve_order)
    test = eval_files(Path(args.data) / args.name, args.limit, 0)
    assets = sorted((ROOT / "tests" / "assets" / f"{args.name}_test").glob("*.png"))
    before, after = measure(shipped, test, assets), measure(scratch, test, assets)
    for tag, m in (("shipped", before), ("phase", after)):
        print(f"{tag:8s} test {m['test_recon_l2']:.5f} ± {m['test_recon_l2_stderr']:.5f}  assets "
              f"{m['assets_recon_l2']:.5f}  fitted {m['assets_fitted_recon_l2']:.5f}", flush=True)
    better = after["test_recon_l2"] < (1 - args.margin) * before["test_recon_l2"]
    print(("ships" if better else "does not beat the shipped model") + f" (step {step}, {len(test)} test images)")
    if better and not args.dry_run:
        ship(run, scratch, shipped, step, len(test), before, after, args.feedback, args.commit or _commit(),
             exported and exported.get("device", "GPU"), args.select, args.path_passes, args.solve_colors,
             args.solve_order, args.point_passes, args.raw)
        print(f"shipped into {shipped}: commit it")


def candidate(args, shipped: Path, run: Path | None) -> tuple[Path, int, dict | None]:
    """The phase's model folder made in scratch (a run's checkpoint exported, a lent GPU's export, or the
    shipped model with more passes): (its folder, its step, the lent GPU's export.json or ``None``)."""
    scratch = run / "ship" if run else ROOT / "runs" / (f"ship-{args.name}-feedback{args.feedback}{'-select' * args.select}"
                                                       f"-path{args.path_passes}-point{args.point_passes}{'-colors' * args.solve_colors}"
                                                       f"{'-order' * args.solve_order}")
    if scratch.exists():
        shutil.rmtree(scratch)
    exported = json.loads((run / "export.json").read_text()) if run and (run / "export.json").is_file() else None
    if exported:  # trained on a lent GPU (bench/device_phases.py): its checkpoint stayed there, its fp16 export
        shutil.copytree(run / "exported", scratch)  # came back
        step = exported["step"]
    elif run:
        _, step = export_checkpoint(run, scratch, half=stored_half(shipped), raw=args.raw)
        if json.loads((run / "train_config.json").read_text()).get("train_only") in ("path_pass", "point_pass"):
            for name in (PRIOR_CONFIG, PRIOR_WEIGHTS, NEIGHBOURS_CONFIG, NEIGHBOURS_WEIGHTS):  # the encoder is the
                if (shipped / name).is_file():  # shipped one, so are its latents: its priors hold as they are
                    shutil.copy2(shipped / name, scratch / name)
        near = shipped / NEIGHBOURS_CONFIG
        if near.is_file() and not (scratch / near.name).is_file():  # the run stopped before it fitted one
            from im2vec_cli.api import fit_neighbours

            cfg = json.loads(near.read_text())
            fit_neighbours(Path(args.data) / args.name, str(scratch), str(scratch), neighbours=cfg["neighbours"],
                           seed=cfg["seed"], overwrite=True)
    elif args.feedback:
        step = with_passes(shipped, scratch, args.feedback, Path(args.data) / args.name, args.select)
    else:
        shutil.copytree(shipped, scratch)
        step = _shipped_step(shipped)
    return scratch, step, exported


def measure(model_dir: Path, test: list[Path], assets: list[Path]) -> dict[str, float]:
    m = from_pretrained(model_dir)
    t = reconstruction_l2(m, test)
    out = {"test_recon_l2": t["recon_l2"], "test_recon_l2_stderr": t["recon_l2_stderr"]}
    out.update({f"test_{k}": t[k] for k in ("outline_iou", "chamfer_px") if k in t})
    out["assets_recon_l2"] = reconstruction_l2(m, assets, outlines=False)["recon_l2"]
    out["assets_fitted_recon_l2"] = reconstruction_l2(m, assets, outlines=False, fit=True)["recon_l2"]
    return out


def with_passes(shipped: Path, scratch: Path, passes: int, data: Path, select: bool = False) -> int:
    """``scratch``: the shipped model with ``passes`` feedback passes (``select``: and
    ``feedback_select``) and its priors refitted
    (same components, shrink, neighbours and seed) to the latents they give; returns the shipped step."""
    from im2vec_cli.api import fit_prior
    from im2vec_cli.config import ModelConfig

    config = ModelConfig.load(shipped / "config.json")
    if not config.feedback:
        raise SystemExit(f"{shipped} has no feedback module to apply again: train one first")
    shutil.copytree(shipped, scratch)
    atomic_write(scratch / "config.json", dataclasses.replace(config, feedback=passes, feedback_select=select).to_json())
    prior = json.loads((shipped / PRIOR_CONFIG).read_text())
    near = shipped / NEIGHBOURS_CONFIG
    k = json.loads(near.read_text())["neighbours"] if near.is_file() else DEFAULT_NEIGHBOURS
    fit_prior(data, str(scratch), str(scratch), components=prior["components"], seed=prior["seed"],
              shrink=prior.get("shrink", 1e-4), neighbours=k, overwrite=True)
    return _shipped_step(shipped)


def _shipped_step(shipped: Path) -> int:
    """The training steps of the shipped model (its metrics.json)."""
    return json.loads((shipped / "metrics.json").read_text()).get("step", 0)


def with_path_passes(scratch: Path, passes: int, kind: str = "path") -> None:
    """``scratch``'s model run with ``passes`` passes of its one ``kind`` pass applied again
    (``"path"``: ``PathPass``, ``ModelConfig.path_passes``; ``"point"``: ``PointPass``, ``point_passes``)."""
    from im2vec_cli.config import ModelConfig

    key = f"{kind}_passes"
    if not getattr(ModelConfig.load(scratch / "config.json"), key):
        raise SystemExit(f"{scratch} has no {kind} pass to apply again: train one first")
    with_config(scratch, **{key: passes})


def with_config(scratch: Path, **changes) -> None:
    """``scratch``'s config.json with ``changes`` (``ModelConfig`` keys, checked as it checks them)."""
    from im2vec_cli.config import ModelConfig

    config = ModelConfig.load(scratch / "config.json")
    atomic_write(scratch / "config.json", dataclasses.replace(config, **changes).to_json())


def ship(run: Path | None, scratch: Path, shipped: Path, step: int, n_test: int, before: dict, after: dict,
         passes: int | None = None, commit: str = "unknown", device: str | None = None, select: bool = False,
         path_passes: int | None = None, solve_colors: bool = False, solve_order: bool = False,
         point_passes: int | None = None, raw: bool = False, history: Path | None = None) -> None:
    """``device``: the lent GPU the run trained on (bench/device_phases.py), if it did; ``history``: the
    file the phase's section is appended to (default docs/results/history-<shipped's name>.md)."""
    metrics = json.loads((shipped / "metrics.json").read_text())
    phase = metrics.get("earlier_phases", 0) + len(metrics.get("phases", [])) + 1  # earlier: before this script
    events, cfg, started, added = [], {}, None, 0  # no run (``passes``): no steps, no curve
    if run:
        events = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
        cfg = json.loads((run / "train_config.json").read_text())
        started = _started(events)
        added, events = phase_span(metrics.get("phases", []), events, step)
    entry = {"phase": phase, "date": time.strftime("%Y-%m-%d", time.gmtime()), "commit": commit,
             "steps": step, "steps_added": added, "of_steps": cfg.get("steps", step),
             "minutes": round(_minutes(events), 1), "run_started": started, "test_images": n_test,
             "before": before, "after": after, **({"feedback": passes, "select": select} if passes else {}),
             **({"path_passes": path_passes} if path_passes else {}),
             **({"point_passes": point_passes} if point_passes else {}), **({"raw_weights": True} if raw else {}),
             **({"solve_colors": True} if solve_colors else {}),
             **({"solve_order": True} if solve_order else {}),
             **({} if run else {"untrained": True}),
             **({"device": device} if device else {})}
    # the card's own figure when it was measured on the whole test split (emoji, icons), else the seeded subset's
    key = "test_recon_l2" if metrics.get("test_images") == n_test else f"test_split_{n_test}_recon_l2"
    replaced = {k: metrics[k] for k in (key, key + "_stderr", "assets_subset_recon_l2",
                                         "assets_subset_fitted_recon_l2", "outline_iou_4x", "chamfer_px")
                if k in metrics}
    metrics["step"] = metrics.get("step", 0) + added
    if "training" in metrics:  # what RESULTS.md's provenance shows
        metrics["training"] = training_with(metrics["training"], entry)
    metrics.update({key: after["test_recon_l2"], key + "_stderr": after["test_recon_l2_stderr"],
                    "assets_subset_recon_l2": after["assets_recon_l2"],
                    "assets_subset_fitted_recon_l2": after["assets_fitted_recon_l2"],
                    f"before_phase_{phase}": replaced, "phases": [*metrics.get("phases", []), entry]})
    for k, test_key in (("outline_iou_4x", "test_outline_iou"), ("chamfer_px", "test_chamfer_px")):
        if test_key in after:
            metrics[k] = after[test_key]

    def write(tmp: Path) -> None:
        for f in shipped.iterdir():  # the card's own files (README, metrics, segments.json, ...)
            if f.is_file() and f.name not in MODEL_FILES:
                shutil.copy2(f, tmp / f.name)
        for name in MODEL_FILES:
            if (scratch / name).is_file():
                shutil.copy2(scratch / name, tmp / name)
        atomic_write(tmp / "metrics.json", json.dumps(metrics, indent=1) + "\n")

    replace_folder(shipped, write)
    history = history or ROOT / "docs" / "results" / f"history-{shipped.name}.md"  # one section a phase
    earlier = history.read_text().rstrip() + "\n\n" if history.is_file() else ""
    atomic_write(history, earlier + card_section(entry, cfg, events) + "\n")
    if shipped.resolve().parent == ROOT / "models":
        figures.write()  # the card's "How good" block and README's tables, from the new metrics.json


def _commit() -> str:
    out = subprocess.run(["git", "-C", str(ROOT), "describe", "--always", "--dirty"], capture_output=True, text=True)
    return out.stdout.strip() or "unknown"


if __name__ == "__main__":
    main()
