"""Training phases on a lent GPU machine within its budget (issue 37: "a prepared script trains there").

The ``device`` tool lends, to some tasks, one GPU machine for about 15 minutes in all, starts
included; it runs one command (10 minutes at most) over a copy of the checkout (64 MiB at most)
and brings back at most 8 files of 16 MiB from ``$OUT``. This script fits a phase of several
models into one such command, in three steps:

``pack`` (here): ``.gpu/`` (ignored by git; the command names it in ``carry``) gets, per set
(a run ``SET.TAG`` is another phase of SET, e.g. a control beside it, sharing its pictures),
the PNGs of DATA/<set>/{train,val}, the shipped weights the phase starts from
(``models/<set>``'s config.json and model.safetensors) and the phase's config, plus the
wheels the machine lacks (svgwrite, the SVG writer's test reference). It prints the bytes that travel.

``run`` (there, ``python3 bench/device_phases.py run --seconds S``): all sets train at once on
the one GPU, each as ``im2vec train --init``. A short calibration run per set first (killed once
it has logged its speed) tells how many steps fit before ``S`` less the time kept for the end,
so that each phase's cosine schedule ends inside it (``--minutes`` stops a phase that runs
slow). Each run then fits its latent prior, unless the end comes first (``unpack`` fits it
here then; a prior fitted to a ``--thin`` set is better refitted here to the whole one, ``im2vec
fit-prior``). ``$OUT/<set>.tar`` holds the run's exported model (fp16, as shipped),
metrics.jsonl and train_config.json, ``$OUT/<set>.log`` its log, ``$OUT/device.txt`` the timings.

``unpack`` (here): each tar into ``runs/<set>-device/``, the latent prior fitted where it came
back without one; then ``python bench/ship_phase.py runs/<set>-device --set <set> --data DATA
--commit <sha>`` measures and ships it as it does a phase trained here.

    python bench/device_phases.py pack --data DATA --phase emoji=models/phases/emoji-feedback3.json ...
    # the device tool: run(command="python3 bench/device_phases.py run --seconds 520", carry=[".gpu"])
    python bench/device_phases.py unpack DIR --data DATA
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tarfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACK = ROOT / ".gpu"
WHEELS = ("svgwrite==1.4.3",)  # what the machine's image lacks (the dev extras' reference for the SVG writer)
END_SECONDS = 50  # kept after training: the latent prior (if it fits in), the fp16 export and the tars
STARTUP_SECONDS = 30  # a run's model, pictures and first steps before its speed holds (MNIST's 25,000 PNGs: ~20 s)
CALIBRATION_LOGS = 3  # logged train events (every 10 steps) a speed is measured over


def pack(data: Path, phases: dict[str, Path], thin: dict[str, int]) -> None:
    """``thin``: every Nth training picture of a set (and validation pictures as many as train
    uses, ``VAL_IMAGES``), where a set's pictures would not fit in what travels."""
    sys.path.insert(0, str(ROOT / "src"))
    from im2vec_cli.training.train import VAL_IMAGES

    shutil.rmtree(PACK, ignore_errors=True)
    PACK.mkdir()
    for name, config in phases.items():
        shutil.copy2(config, PACK / f"{name}.json")
        name = _set(name)
        if (PACK / "init" / name).is_dir():  # a second run of the set (a control) shares its pictures
            continue
        for split in ("train", "val"):
            src = data / name / split
            pngs = sorted(src.rglob("*.png"))  # MNIST's are in a folder per class
            every = thin.get(name, 1) if split == "train" else max(1, len(pngs) // VAL_IMAGES)
            for png in pngs[::every]:
                dst = PACK / "data" / name / split / png.relative_to(src)
                dst.parent.mkdir(parents=True, exist_ok=True)
                os.link(png, dst)
        init = PACK / "init" / name
        init.mkdir(parents=True)
        for f in ("config.json", "model.safetensors"):
            shutil.copy2(ROOT / "models" / name / f, init / f)
    (PACK / "whl").mkdir()
    subprocess.run([sys.executable, "-m", "pip", "download", "-q", "--no-deps", "--only-binary=:all:",
                    "--python-version", "3.12", "--implementation", "cp", "--platform", "manylinux2014_x86_64",
                    "-d", str(PACK / "whl"), *WHEELS], check=True)
    size = sum(f.stat().st_size for f in PACK.rglob("*") if f.is_file())
    print(f"{PACK}: {size / 2**20:.1f} MiB for {', '.join(phases)}")


def _set(name: str) -> str:
    """A run's set: ``icons`` for ``icons`` and for ``icons.control`` (two runs of one set)."""
    return name.split(".")[0]


def _train(name: str, out: Path, seconds: float, extra: list[str], log: Path, device: str) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "im2vec_cli", "train", str(PACK / "data" / _set(name)), "--out", str(out),
           "--init", str(PACK / "init" / _set(name)), "--device", device, "--overwrite", "--workers", "4",
           "--minutes", f"{seconds / 60:.3f}", *extra]
    return subprocess.Popen(cmd, stdout=log.open("w"), stderr=subprocess.STDOUT, start_new_session=True)


def _logged(metrics: Path) -> list[tuple[int, float]]:
    """(step, time) of a run's logged train events."""
    if not metrics.is_file():
        return []
    return [(e["step"], e["time"]) for e in map(json.loads, metrics.read_text().splitlines()) if e["event"] == "train"]


def calibrate(names: list[str], work: Path, limit: float, device: str) -> dict[str, float]:
    """Steps per second of each set's phase, measured only while all of them train at once, as
    they will (one still loading its pictures leaves the GPU to the others: 1.5x too fast)."""
    procs, since, speeds = {}, {}, {}
    for name in names:
        cfg = json.loads((PACK / f"{name}.json").read_text())
        cfg["train"].update(log_every=10, val_every=10**6, ckpt_every=10**6, preview_every=10**6, steps=10**5)
        (work / f"cal-{name}.json").write_text(json.dumps(cfg))
        procs[name] = _train(name, work / f"cal-{name}", limit, ["--config", str(work / f"cal-{name}.json")],
                             work / f"cal-{name}.log", device)
    t0 = time.monotonic()
    while len(speeds) < len(names) and time.monotonic() - t0 < limit:
        time.sleep(2)
        logged = {n: _logged(work / f"cal-{n}" / "metrics.jsonl") for n in names}
        if not since and all(logged.values()):  # all train from here: each one's last event starts its window
            since = {n: ev[-1] for n, ev in logged.items()}
        for n in since:
            later = [e for e in logged[n] if e[0] > since[n][0]]
            if n not in speeds and len(later) >= CALIBRATION_LOGS:
                speeds[n] = (later[-1][0] - since[n][0]) / (later[-1][1] - since[n][1])
    for p in procs.values():
        _stop(p)
    missing = [n for n in names if n not in speeds]
    if missing:
        logs = {n: (work / f"cal-{n}.log").read_text()[-800:] for n in missing}
        raise SystemExit(f"calibration logged no speed for {missing}: {logs}")
    return speeds


def _stop(p: subprocess.Popen) -> None:
    """End a run (its checkpoint is written, atomically, when it stops training)."""
    if p.poll() is None:
        os.killpg(p.pid, signal.SIGTERM)
        try:
            p.wait(5)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()


def run(seconds: float, out: Path, device: str) -> None:
    t0 = time.monotonic()
    import torch

    if device == "cuda" and not torch.cuda.is_available():
        raise SystemExit("no CUDA device")
    # each run: a few CPU threads of the machine's 16; the renderer eager (a compile per shape costs
    # more than a phase of a few minutes gains)
    os.environ.update(OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "4"),
                      IM2VEC_COMPILE=os.environ.get("IM2VEC_COMPILE", "0"),
                      PYTHONPATH=os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]))
    names = sorted(p.stem for p in PACK.glob("*.json"))
    work = Path("/tmp/device-phases")
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir()
    gpu = torch.cuda.get_device_name() if device == "cuda" else device
    report = [f"{gpu}, torch {torch.__version__}, sets {names}"]
    speeds = calibrate(names, work, 150, device)
    report.append(f"calibration {time.monotonic() - t0:.0f} s: " + ", ".join(f"{n} {s:.2f} steps/s"
                                                                          for n, s in speeds.items()))
    train_s = seconds - (time.monotonic() - t0) - END_SECONDS
    procs = {}
    for name in names:
        steps = int(0.93 * speeds[name] * (train_s - STARTUP_SECONDS))
        procs[name] = _train(name, work / name, train_s, ["--config", str(PACK / f"{name}.json"), "--steps",
                                                          str(steps)], out / f"{name}.log", device)
        report.append(f"{name}: {steps} steps planned in {train_s:.0f} s")
    for p in procs.values():  # training, then the latent prior, until the end
        try:
            p.wait(max(1.0, seconds - 25 - (time.monotonic() - t0)))
        except subprocess.TimeoutExpired:
            _stop(p)
    sys.path.insert(0, str(ROOT / "src"))
    from im2vec_cli.model.pretrained import export_checkpoint

    for name in names:
        run_dir = work / name
        try:
            _, step = export_checkpoint(run_dir, run_dir / "exported", half=True)
        except Exception as e:  # noqa: BLE001  (one set's failure must not lose the others)
            report.append(f"{name}: no checkpoint to export ({e})")
            continue
        (run_dir / "export.json").write_text(json.dumps({"step": step, "device": gpu}))
        with tarfile.open(out / f"{name}.tar", "w") as tar:
            for f in ("exported", "export.json", "metrics.jsonl", "train_config.json"):
                tar.add(run_dir / f, arcname=f)
        report.append(f"{name}: step {step}, prior {'yes' if (run_dir / 'exported/latent_prior.json').is_file() else 'no'}")
    report.append(f"total {time.monotonic() - t0:.0f} s")
    (out / "device.txt").write_text("\n".join(report) + "\n")
    print("\n".join(report))


def unpack(src: Path, data: Path) -> None:
    sys.path.insert(0, str(ROOT / "src"))
    from im2vec_cli.api import fit_prior

    for tar_path in sorted(src.glob("*.tar")):
        name = tar_path.stem
        run_dir = ROOT / "runs" / f"{name}-device"
        shutil.rmtree(run_dir, ignore_errors=True)
        with tarfile.open(tar_path) as tar:
            tar.extractall(run_dir, filter="data")
        model = run_dir / "exported"
        if not (model / "latent_prior.json").is_file():  # the end came before the run fitted it
            cfg = json.loads((run_dir / "train_config.json").read_text())
            fit_prior(data / _set(name), str(model), str(model), components=cfg["prior_components"], seed=cfg["seed"],
                      shrink=cfg["prior_shrink"], overwrite=True)
        print(f"{run_dir}: step {json.loads((run_dir / 'export.json').read_text())['step']}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("pack")
    p.add_argument("--data", type=Path, required=True)
    p.add_argument("--phase", action="append", required=True, metavar="SET[.TAG]=CONFIG",
                   help="A phase of SET; SET.TAG names a second run of it (a control).")
    p.add_argument("--thin", action="append", default=[], metavar="SET=N", help="Every Nth training picture of SET.")
    r = sub.add_parser("run")
    r.add_argument("--seconds", type=float, required=True, help="The whole command's time, end included.")
    r.add_argument("--device", default="cuda", help="cpu: try the script here first.")
    u = sub.add_parser("unpack")
    u.add_argument("src", type=Path, help="The folder the device tool brought $OUT's files into.")
    u.add_argument("--data", type=Path, required=True)
    args = ap.parse_args()
    if args.cmd == "pack":
        pack(args.data, {k: Path(v) for k, v in (s.split("=", 1) for s in args.phase)},
             {k: int(v) for k, v in (s.split("=", 1) for s in args.thin)})
    elif args.cmd == "run":
        run(args.seconds, Path(os.environ.get("OUT", "/tmp/out")), args.device)
    else:
        unpack(args.src, args.data)


if __name__ == "__main__":
    main()
