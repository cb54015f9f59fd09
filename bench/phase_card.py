"""A shipped phase's history section and training summary (bench/ship_phase.py writes them):
what the phase ran, its figures before and after, and its validation curve."""

from __future__ import annotations

import json

CURVE_ROWS = 12  # validation rows of the section's curve (evenly spread, the last one always)


def card_section(entry: dict, cfg: dict, events: list[dict]) -> str:
    b, a = entry["before"], entry["after"]
    head = [f"## Phase {entry['phase']} ({entry['date']}, code at {entry['commit']}): the shipped weights", ""]
    paths = (f" Run with {entry['path_passes']} passes of its path pass (`\"path_passes\": {entry['path_passes']}` "
             f"in config.json, `--path-passes {entry['path_passes']}`)." if entry.get("path_passes") else "")
    paths += (f" Run with {entry['point_passes']} passes of its point pass (`\"point_passes\": {entry['point_passes']}` "
              f"in config.json, `--point-passes {entry['point_passes']}`)." if entry.get("point_passes") else "")
    paths += (" The run's trained weights are shipped, not their EMA (`--raw`: the average of a run this short "
              "still lags them; the curve's raw columns)." if entry.get("raw_weights") else "")
    paths += (" Its layers' colours are solved per picture by least squares once the shapes are drawn "
              "(`\"solve_colors\": true` in config.json, `--solve-colors`; `raster.solve_colors`)."
              if entry.get("solve_colors") else "")
    paths += (" Before that, the layers' order is searched per picture, each order scored by its solved render "
              "(`\"solve_order\": true`, `--solve-order`; `raster.solve_order`)." if entry.get("solve_order") else "")
    if entry.get("untrained") and "feedback" not in entry:
        lines = head + [f"No training: the weights of phase {entry['phase'] - 1}." + paths, ""]
        return "\n".join(lines + _figures(b, a, entry["test_images"]))
    if "feedback" in entry:
        sel = entry.get("select")
        lines = head + [f"No training: the weights of phase {entry['phase'] - 1} with {entry['feedback']} "
                        "render-and-compare passes of its one feedback module (`\"feedback\": "
                        f"{entry['feedback']}` in config.json)" + (", keeping per picture the guess (the encoder's "
                        "or a pass's) whose render is closest to it (`\"feedback_select\": true`)" if sel else "")
                        + ", the latent prior refitted with its own settings to the latents they give "
                        f"(`python bench/ship_phase.py --feedback {entry['feedback']}{' --select' * bool(sel)}`)." + paths, ""]
        return "\n".join(lines + _figures(b, a, entry["test_images"]))
    lines = head + [(f"`python bench/device_phases.py run` on a lent {entry['device']} (`im2vec train DATA --init "
                  "<the shipped model> --config ... --steps <as calibrated> --minutes ... --device cuda`, beside the "
                  "other sets' phases; `python bench/device_phases.py unpack` here" if "device" in entry else
                  "`make train-<set> RESUME=1` (`im2vec train DATA --out RUN --resume --minutes ...`, the run of "
                  "the last phase continued" if _resumed(entry) else
                  "`make train-<set>` (`im2vec train DATA --init <the shipped model> --config "
                  "models/phases/<set>.json --minutes ...`")
             + f", then `python bench/ship_phase.py`): {_steps(entry)} of {entry['of_steps']} steps in "
             f"{entry['minutes']} min" + ("" if "device" in entry else " on this machine") + "." + paths + " With", "",
             "```json", json.dumps({k: v for k, v in cfg.items() if k not in ("class_name", "format_version")}),
             "```", "", *_figures(b, a, entry["test_images"]), "", "Validation (the run's `metrics.jsonl`):", "",
             "| step | min | val pyramid L2 | val MSE | raw val MSE |", "|---|---|---|---|---|"]
    val = [e for e in events if e["event"] == "val"]
    t0 = min(e["time"] for e in events if "time" in e)
    rows = sorted({round(i * (len(val) - 1) / (CURVE_ROWS - 1)) for i in range(CURVE_ROWS)}) if val else []
    for e in (val[i] for i in rows):
        raw = f"{e['raw_val_mse']:.4g}" if "raw_val_mse" in e else "–"
        lines.append(f"| {e['step']} | {(e['time'] - t0) / 60:.0f} | {e['val_pyramid_l2']:.4g} | {e['val_mse']:.4g} | {raw} |")
    return "\n".join(lines)


def _figures(b: dict, a: dict, n_test: int) -> list[str]:
    """The card's before / after table."""
    lines = ["| figure | before | after |", "|---|---|---|",
             f"| test split, {n_test} images: recon L2 | {b['test_recon_l2']:.5f} ± "
             f"{b['test_recon_l2_stderr']:.5f} | {a['test_recon_l2']:.5f} ± {a['test_recon_l2_stderr']:.5f} |"]
    for k, label in (("test_outline_iou", "IoU@4x"), ("test_chamfer_px", "Chamfer (px)")):
        if k in a:
            lines.append(f"| test split: {label} | {b[k]:.4f} | {a[k]:.4f} |")
    return lines + [f"| 64 test-split assets: recon L2 | {b['assets_recon_l2']:.5f} | {a['assets_recon_l2']:.5f} |",
                    f"| 64 assets, fitted (`eval --fit`) | {b['assets_fitted_recon_l2']:.5f} | "
                    f"{a['assets_fitted_recon_l2']:.5f} |"]


def phase_span(phases: list[dict], events: list[dict], step: int) -> tuple[int, list[dict]]:
    """The steps this phase adds to the shipped model, and the run's events of this phase alone.

    A run resumed (``RESUME=1``) after one of its phases shipped carries that phase's steps
    and events too: the last shipped entry with the same ``run_started`` (the run's first
    event) says where this phase began. A run whose earlier phase did not ship adds all its steps.
    """
    last = phases[-1] if phases else {}
    if last.get("run_started") is None or last["run_started"] != _started(events):
        return step, events
    began = last["steps"]
    return step - began, [e for e in events if e.get("step", 0) > began]


def training_with(training: dict, entry: dict) -> dict:
    """The card's ``training`` summary (steps, wall, phases) with this phase added."""
    if "feedback" in entry or entry.get("untrained"):  # no run: steps and wall stay
        how = (f"phase {entry['phase']}: " + ", ".join(
            ([f"{entry['feedback']} feedback passes at inference"] if "feedback" in entry else [])
            + (["the closest kept per picture"] if entry.get("select") else [])
            + ([f"{entry['path_passes']} path passes"] if entry.get("path_passes") else [])
            + ([f"{entry['point_passes']} point passes"] if entry.get("point_passes") else [])
            + (["colours solved per picture"] if entry.get("solve_colors") else [])
            + (["the layers' order searched per picture"] if entry.get("solve_order") else []) + ["no training"]))
        return {**training, "phases": "; ".join(x for x in (training.get("phases"), how) if x)}
    where = f" on a lent {entry['device']}" if "device" in entry else ""  # bench/device_phases.py
    how = (f"the run of phase {entry['phase'] - 1} resumed to {entry['steps']:,} of its {entry['of_steps']:,} steps"
           if _resumed(entry) else f"bench/device_phases.py from phase {entry['phase'] - 1}{where}, "
           f"{entry['steps']:,} steps" if where else f"make train-<set> from phase {entry['phase'] - 1}, "
           f"{entry['steps']:,} steps")
    wall = f"{entry['minutes']:.0f} min" + (" (GPU)" if where else "")
    hardware = {"hardware": f"{training.get('hardware', '?')}; phase {entry['phase']}{where}"} if where else {}
    return {**training, "steps": training.get("steps", 0) + entry["steps_added"],
            "wall": f"{training['wall']} + {wall}" if training.get("wall") else wall, **hardware,
            "phases": "; ".join(x for x in (training.get("phases"), f"phase {entry['phase']}: {how}") if x)}


def _resumed(entry: dict) -> bool:
    """Whether the phase continued a run one of whose phases had shipped (``phase_span``)."""
    return "feedback" not in entry and entry.get("steps_added", entry["steps"]) != entry["steps"]


def _steps(entry: dict) -> str:
    return f"{entry['steps'] - entry['steps_added']} to {entry['steps']}" if _resumed(entry) else str(entry["steps"])


def _started(events: list[dict]) -> float | None:
    return min((e["time"] for e in events if "time" in e), default=None)


def _minutes(events: list[dict]) -> float:
    times = [e["time"] for e in events if "time" in e]
    return (max(times) - min(times)) / 60 if times else 0.0
