"""Vectorize a corpus on Ray (``vectorize --engine ray``): the files are read by Ray Data with
their paths, a callable class (``Vectorizer``) loads the model once per actor and vectorizes each
batch through ``api.vectorize_each`` with the local run's options, and the SVG texts stream back
to the caller, which writes them (the CLI: atomically, under the local run's names).

The same class serves a Ray user's own pipeline::

    ds = ray.data.read_binary_files("s3://bucket/icons/", include_paths=True)
    ds = ds.map_batches(Vectorizer, fn_constructor_kwargs={"model": "icons"}, batch_size=32,
                        compute=ray.data.ActorPoolStrategy(size=8), num_cpus=1)
    ds.select_columns(["path", "svg", "error"]).write_parquet("s3://bucket/svgs/")

Outputs do not depend on how pictures are batched or on the threads (checked byte for byte:
tests/test_rayengine.py), so a cluster's SVGs are the local run's.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator

from .errors import Im2VecError
from .options import VectorizeOptions

BATCH = 32  # pictures an actor vectorizes at once (the local run's chunk)
INSTALL = "pip install 'im2vec[ray]'"


class Vectorizer:
    """A Ray Data callable class (``ds.map_batches(Vectorizer, ...)``): the model is loaded once
    per actor. Each batch's rows hold ``path`` and ``bytes`` (``read_binary_files(...,
    include_paths=True)``), or ``path`` alone (the file is read here, within the local run's
    bounds); they come back as ``path``, ``svg`` (the SVG text, ``""`` when it failed) and
    ``error`` (one line naming the picture, ``""`` when it was vectorized)."""

    def __init__(self, model: str = "fonts", options: VectorizeOptions | None = None, device: str = "auto",
                 seed: int = 0, threads: int = 1):
        from .api import ModelRef
        from .runtime import seed_everything, set_threads

        set_threads(threads)
        seed_everything(seed)
        self.model, self.options = ModelRef(model, device), options or VectorizeOptions()  # loaded where needed

    def __call__(self, batch: dict) -> dict:
        from .api import vectorize_each
        from .files import load_picture

        paths = [str(p) for p in batch["path"]]
        data = batch.get("bytes")
        errors, svgs, good = [""] * len(paths), [""] * len(paths), []
        for i, path in enumerate(paths):
            try:
                raw = None if data is None else bytes(data[i])
                good.append((i, load_picture(path, raw, self.options.max_input_pixels())))
            except Im2VecError as exc:
                errors[i] = str(exc)
        for (i, _), vec in zip(good, vectorize_each([p for _, p in good], self.model, self.options)):
            if isinstance(vec, Exception):
                errors[i] = f"{paths[i]}: {vec}"
            else:
                svgs[i] = vec.to_svg()
        return {"path": paths, "svg": svgs, "error": errors}


def vectorize_on_ray(paths: list[str], model: str = "fonts", options: VectorizeOptions | None = None, *,
                     jobs: int | None = None, address: str | None = None, device: str = "auto",
                     seed: int = 0) -> Iterator[tuple[str, str | Im2VecError]]:
    """``(path, SVG text or the error of that picture)`` for each of ``paths`` (absolute, readable
    where the actors run), as the actors finish them, in no set order.

    ``address``: the cluster (``None``: ``RAY_ADDRESS``, else a local cluster on this host, ended
    when the work ends). ``jobs``: the actors (default and most: the cluster's CPUs, or its GPUs when
    it has them and ``device`` allows: one GPU an actor). A file over the local run's input bound is its
    own error, never read. Raises ``Im2VecError`` (one line) without Ray installed."""
    from .files import MAX_INPUT_BYTES

    ray = _ray()
    started = not ray.is_initialized()
    if started:
        ray.init(address=address, include_dashboard=False, log_to_driver=False, logging_level=logging.ERROR)
    try:
        readable = []
        for p in paths:
            size = os.stat(p).st_size if os.path.isfile(p) else -1
            if 0 <= size <= MAX_INPUT_BYTES:
                readable.append(p)
            else:
                yield p, Im2VecError(f"{p}: not a regular file of at most {MAX_INPUT_BYTES // 2**20} MiB")
        if readable:
            yield from _run(ray, readable, model, options or VectorizeOptions(), jobs, device, seed)
    finally:
        if started:
            ray.shutdown()


def _run(ray, paths: list[str], model: str, options: VectorizeOptions, jobs: int | None, device: str, seed: int):
    resources = ray.cluster_resources()
    gpus = int(resources.get("GPU", 0)) if device in ("auto", "cuda") or device.startswith("cuda:") else 0
    most = gpus or max(1, int(resources.get("CPU", 1)))  # more actors than the cluster holds would wait forever
    size = min(jobs or most, most)
    per_actor = {"num_gpus": 1} if gpus else {"num_cpus": 1}
    ds = ray.data.read_binary_files(paths, include_paths=True, num_cpus=0)  # reading waits on disks, not CPUs
    ds = ds.map_batches(Vectorizer, batch_size=BATCH, compute=ray.data.ActorPoolStrategy(size=min(size, len(paths))),
                        fn_constructor_kwargs={"model": model, "options": options, "seed": seed,
                                               "device": "cuda" if gpus else device}, **per_actor)
    rows = iter(ds.select_columns(["path", "svg", "error"]).iter_rows())  # a generator: close() ends the execution
    try:
        for row in rows:
            yield row["path"], Im2VecError(row["error"]) if row["error"] else row["svg"]
    finally:  # an interrupt: Ray Data's threads stopped before Ray is (else Ray ends the process, exit 1)
        rows.close()
        _join_data_threads()


DATA_THREADS = ("iter_threaded", "Prefetcher", "StreamingExecutor")  # Ray Data's own threads (names' starts)


def _join_data_threads(timeout: float = 30.0) -> None:
    """Wait (at most ``timeout`` s in all) for Ray Data's iteration threads to end once their
    iterator is closed: one still asking for a block when Ray shuts down makes Ray end the whole
    process with exit 1 (an interrupted run exited 1 instead of 130, one run in two)."""
    import threading
    import time

    deadline = time.monotonic() + timeout
    for thread in threading.enumerate():
        if thread is not threading.current_thread() and thread.name.startswith(DATA_THREADS):
            thread.join(max(0.0, deadline - time.monotonic()))


def _ray():
    """Ray and Ray Data, quiet (their progress bars and INFO lines off stderr), or one line saying
    how to install them."""
    try:
        import ray
        import ray.data
    except ImportError:
        raise Im2VecError(f"--engine ray needs Ray (Ray Data): {INSTALL}") from None
    for name in ("ray", "ray.data"):
        logging.getLogger(name).setLevel(logging.ERROR)
    ctx = ray.data.DataContext.get_current()
    ctx.enable_progress_bars = ctx.enable_operator_progress_bars = False
    ctx.print_on_execution_start = False
    return ray
