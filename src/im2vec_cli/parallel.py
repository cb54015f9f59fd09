"""Worker processes for vectorizing many pictures (``vectorize --jobs N``).

Refinement is partly Python and NumPy work on one core (tracing, curve fitting, untangling)
and partly batched tensor work; on 2 cores, two processes of one thread each refine a folder
of held-out glyphs about 1.5x faster than one process of two threads (bench/folder.py). Each
worker loads its own copy of the model; chunks of pictures go out and vector images come
back, in order. Nothing here prints; Ctrl-C is the parent's to handle (the workers ignore it
and are ended with the pool). A worker's death breaks its pool (``concurrent.futures``), which
is noticed at once: ``multiprocessing.Pool`` replaced the worker and waited forever on its task.
"""

from __future__ import annotations

import collections
import multiprocessing
import signal
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from .events import WorkerDied
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
                     device: str = "auto", seed: int = 0, options: VectorizeOptions | None = None,
                     on_event: Callable[[WorkerDied], None] | None = None) -> Iterator[list]:
    """``api.vectorize_each(chunk, model, options)`` for each chunk of pictures, in ``jobs``
    worker processes (each with ``threads`` torch threads, default the free cores shared
    among the jobs, ``runtime.free_cores``, and the model
    ``model_ref``, a name or a folder). Yields each chunk's vector images in the order of
    the chunks (a picture that failed is a ``VectorizeError`` in its place); at most
    ``2 * jobs`` chunks are in flight, so memory stays bounded for any number of chunks.

    A worker that dies (killed, out of memory, a crash in native code) is noticed, never waited
    on: ``on_event`` hears ``WorkerDied``, the chunks in flight are vectorized again one at a time
    in a fresh worker, and the pictures of a chunk whose worker dies again fail (named)."""
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    if threads is None:
        from .runtime import free_cores

        threads = max(1, free_cores() // jobs)
    args = (model_ref, device, seed, threads, options)
    pool, spare = _Pool(jobs, args), _Pool(1, args)
    pending: collections.deque = collections.deque()
    done = False
    try:
        for chunk in chunks:
            pending.append((chunk, pool.submit(chunk)))
            while len(pending) >= 2 * jobs:
                yield from _next(pool, spare, pending, on_event)
        while pending:
            yield from _next(pool, spare, pending, on_event)
        done = True
    finally:
        pool.end(graceful=done)
        spare.end(graceful=done)


def _next(pool: _Pool, spare: _Pool, pending: collections.deque, on_event) -> Iterator[list]:
    """The results of the oldest chunk in flight; after a worker's death, of every chunk that was."""
    future = pending[0][1]
    try:
        out = future.result()
    except BrokenProcessPool:  # every chunk in flight is lost with the pool: each is run again alone
        lost = [c for c, _ in pending]
        pending.clear()
        died = pool.end(graceful=False)
        if on_event is not None:
            on_event(WorkerDied(died, sum(len(c) for c in lost)))
        for c in lost:
            yield spare.alone(c)
        return
    pending.popleft()
    yield out


class _Pool:
    """A process pool started on first use (forkserver: one import of torch, forked per worker),
    started again after it broke."""

    def __init__(self, jobs: int, args: tuple):
        self.jobs, self.args, self.executor = jobs, args, None

    def submit(self, chunk: list):
        if self.executor is None:
            if "forkserver" in multiprocessing.get_all_start_methods():
                ctx = multiprocessing.get_context("forkserver")
                ctx.set_forkserver_preload(["im2vec_cli.api"])
            else:  # Windows
                ctx = multiprocessing.get_context("spawn")
            self.executor = ProcessPoolExecutor(self.jobs, mp_context=ctx, initializer=_init, initargs=self.args)
        try:
            return self.executor.submit(_run, chunk)
        except BrokenProcessPool as exc:  # broken since the last result was taken: this chunk is lost with it
            lost: Future = Future()
            lost.set_exception(exc)
            return lost

    def alone(self, chunk: list) -> list:
        """``chunk``'s results from this pool, or, when its worker dies on it, an error in each
        picture's place."""
        from .errors import VectorizeError

        try:
            return self.submit(chunk).result()
        except BrokenProcessPool:
            died = self.end(graceful=False)
            why = f" (killed by {signal.Signals(died).name})" if died in signal.valid_signals() else ""
            return [VectorizeError(f"could not vectorize: a worker process died on it{why}")] * len(chunk)

    def end(self, graceful: bool) -> int:
        """Stop the pool: let its workers finish (``graceful``) or end them now. Returns the signal
        that ended a dead worker, else 0."""
        if self.executor is None:
            return 0
        workers = list((getattr(self.executor, "_processes", None) or {}).values())
        died = next((-w.exitcode for w in workers if w.exitcode is not None and w.exitcode < 0), 0)
        self.executor.shutdown(wait=graceful, cancel_futures=not graceful)
        if not graceful:
            for w in workers:
                if w.exitcode is None:
                    w.terminate()
            for w in workers:
                w.join(5)
        self.executor = None
        return died
