"""Helpers shared by the benchmarks: timing, peak memory of a child process, workloads."""

from __future__ import annotations

import json
import math
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time

import torch


def star_paths(b: int, p: int, s: int, seed: int = 0) -> torch.Tensor:
    """Random star-like closed paths ``(B, P, 3S, 2)`` in the normalised frame."""
    g = torch.Generator().manual_seed(seed)
    ang = torch.linspace(0, 2 * math.pi, 3 * s + 1)[:-1]
    centre = torch.rand(b, p, 1, 2, generator=g) * 0.4 + 0.3
    radius = torch.rand(b, p, 1, 1, generator=g) * 0.2 + 0.1
    wobble = 1 + 0.25 * torch.randn(b, p, 3 * s, 1, generator=g)
    return centre + radius * wobble * torch.stack([ang.cos(), ang.sin()], -1)


def timeit(fn, repeat: int = 5) -> float:
    """Best wall time of ``repeat`` calls, in seconds (the first call is not counted)."""
    fn()
    best = math.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def maxrss_bytes() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def run_child(script: str, *args: str, cold_compile: bool = False) -> dict:
    """Run ``python script args`` and parse the JSON it prints last (a fresh process per
    measurement keeps peak-memory figures separate). ``cold_compile`` gives the child an
    empty inductor cache, so that its first call pays the whole ``torch.compile`` cost."""
    env = None
    if cold_compile:
        cache = tempfile.mkdtemp(prefix="im2vec-inductor-")
        env = {**os.environ, "TORCHINDUCTOR_CACHE_DIR": cache, "TRITON_CACHE_DIR": os.path.join(cache, "triton")}
    try:
        out = subprocess.run([sys.executable, script, *args], capture_output=True, text=True, env=env)
    finally:
        if cold_compile:
            shutil.rmtree(cache, ignore_errors=True)
    if out.returncode != 0:
        return {"error": (out.stderr.strip().splitlines() or ["failed"])[-1]}
    return json.loads(out.stdout.strip().splitlines()[-1])
