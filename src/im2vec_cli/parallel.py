"""Worker processes for vectorizing many pictures (``vectorize --jobs N``).

Refinement is partly Python and NumPy work on one core (tracing, curve fitting, untangling)
and partly batched tensor work; on 2 cores, two processes of one thread each refine a folder
of held-out glyphs about 1.5x faster than one process of two threads (bench/folder.py). Each
worker loads its own copy of the model; chunks of pictures go out and vector images come
back, in order. Nothing here prints; Ctrl-C is the parent's to handle (the workers ignore it
and are ended with the pool).
"""

from __future__ import annotations

import collections
import multiprocessing
import signal
from collections.abc import Iterable, Iterator

from .options import VectorizeOptions

_state: dict = {}


def _init(model_ref: str, device: str, seed: int, threads: int, options: VectorizeOptions | None) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C and ends the pool

    from .api import load_model
    from .runtime import seed_everything, set_threads

    set_threads(threads)
    seed_everything(seed)
    _state.update(model=load_model(model_ref, device), options=options)


def _run(pictures: list) -> list:
    from .api import vectorize_each

    return vectorize_each(pictures, _state["model"], _state["options"])


def vectorize_chunks(chunks: Iterable[list], model_ref: str, *, jobs: int, threads: int | None = None,
                     device: str = "auto", seed: int = 0, options: VectorizeOptions | None = None
                     ) -> Iterator[list]:
    """``api.vectorize_each(chunk, model, options)`` for each chunk of pictures, in ``jobs``
    worker processes (each with ``threads`` torch threads, default the free cores shared
    among the jobs, ``runtime.free_cores``, and the model
    ``model_ref``, a name or a folder). Yields each chunk's vector images in the order of
    the chunks (a picture that failed is a ``VectorizeError`` in its place); at most
    ``2 * jobs`` chunks are in flight, so memory stays bounded for any number of chunks."""
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    if threads is None:
        from .runtime import free_cores

        threads = max(1, free_cores() // jobs)
    if "forkserver" in multiprocessing.get_all_start_methods():  # one import of torch, forked per worker
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["im2vec_cli.api"])
    else:  # Windows
        ctx = multiprocessing.get_context("spawn")
    pool = ctx.Pool(jobs, _init, (model_ref, device, seed, threads, options))
    done = False
    try:
        pending: collections.deque = collections.deque()
        for chunk in chunks:
            pending.append(pool.apply_async(_run, (chunk,)))
            if len(pending) >= 2 * jobs:
                yield pending.popleft().get()
        while pending:
            yield pending.popleft().get()
        done = True
    finally:
        if done:  # let the workers exit on their own (and end their compile workers, if any)
            pool.close()
        else:  # Ctrl-C, an error, or the caller stopped early: end them now
            pool.terminate()
        pool.join()
