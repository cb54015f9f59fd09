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
import warnings
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from .errors import OptionWarning
from .events import WorkerDied
from .options import Plan, VectorizeOptions

_state: dict = {}
TRACE_IMPORTS = ["cv2", "contourpy", "pathops", "numpy.ma", "xml.etree.ElementTree", "PIL.PngImagePlugin",
                 "PIL.JpegImagePlugin"]  # what tracing imports on first use (numpy.ma: np.unique's):
# once in the fork server, not once a worker


def _init(model_ref: str, device: str, seed: int, threads: int, options: VectorizeOptions | None) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C and ends the pool
    warnings.simplefilter("ignore", OptionWarning)  # said once, by vectorize_chunks in the parent

    from .runtime import seed_everything, set_threads
    from .vectorizing import ModelRef

    set_threads(threads)
    seed_everything(seed)
    _state.update(model=ModelRef(model_ref, device), options=options)  # loaded where a picture needs it


def _run(pictures: list) -> list:
    from .api import vectorize_each

    return vectorize_each(pictures, _state["model"], _state["options"])


def vectorize_chunks(chunks: Iterable[list], model_ref: str, *, jobs: int, threads: int | None = None,
                     device: str = "auto", seed: int = 0, options: VectorizeOptions | None = None,
                     on_event: Callable[[WorkerDied], None] | None = None, model: bool = True) -> Iterator[list]:
    """``api.vectorize_each(chunk, model, options)`` for each chunk of pictures, in ``jobs``
    worker processes (each with ``threads`` torch threads, default the free cores shared
    among the jobs, ``runtime.free_cores``, and the model
    ``model_ref``, a name or a folder). Yields each chunk's vector images in the order of
    the chunks (a picture that failed is a ``VectorizeError`` in its place); at most
    ``2 * jobs`` chunks are in flight, so memory stays bounded for any number of chunks.

    A worker that dies (killed, out of memory, a crash in native code) is noticed, never waited
    on: ``on_event`` hears ``WorkerDied``, the chunks in flight are vectorized again one at a time
    in a fresh worker, and the pictures of a chunk whose worker dies again fail (named).

    ``model``: some pictures will need the model: torch is imported once, before the workers fork
    (else each worker imports it where a picture first needs it)."""
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    if threads is None:
        from .runtime import free_cores

        threads = max(1, free_cores() // jobs)
    if options is not None:
        from .vectorizing import set_fields, warn_idle

        warn_idle(options, set_fields(options))  # once here: the workers keep quiet
    args = (model_ref, device, seed, threads, options)
    preload = ["im2vec_cli.api", *TRACE_IMPORTS] + (["im2vec_cli.refine.batch", "im2vec_cli.infer"] if model else [])
    pool, spare = _Pool(jobs, args, preload), _Pool(1, args, preload)
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
    """A process pool started on first use (forkserver: ``preload``'s modules imported once, forked
    per worker), started again after it broke."""

    def __init__(self, jobs: int, args: tuple, preload: list[str]):
        self.jobs, self.args, self.preload, self.executor = jobs, args, preload, None

    def submit(self, chunk: list):
        if self.executor is None:
            if "forkserver" in multiprocessing.get_all_start_methods():
                ctx = multiprocessing.get_context("forkserver")
                ctx.set_forkserver_preload(self.preload)
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
        manager = getattr(self.executor, "_executor_manager_thread", None)  # shutdown forgets it
        self.executor.shutdown(wait=graceful, cancel_futures=not graceful)
        if not graceful:
            for w in workers:
                if w.exitcode is None:
                    w.terminate()
            for w in workers:
                w.join(5)
            if manager is not None:  # it closes the pool's wakeup pipe as it ends: waited for, else the exit's
                manager.join(5)  # own wakeup of that thread can race the close ("Bad file descriptor", Python 3.11)
        self.executor = None
        return died


# What a folder costs, for ``plan_jobs`` (2-core machine, bench/speed.py's pictures; seconds)
WORKER_START = 0.4  # a worker process: Python, NumPy, Pillow and im2vec's tracing imported
MODEL_START = 2.5  # torch and the model loaded in a worker (or in the process) whose pictures need them
TRACE_PICTURE = 0.05  # a traced picture: per picture, ...
TRACE_MEGAPIXEL = 1.5  # ... and per million pixels
MODEL_PICTURE = 0.15  # a picture refined or drawn by the model, in a batch


def plan_workers(options: VectorizeOptions, sides: list[tuple[int, int] | None], count: int, *, most: int,
         jobs: int | None = None, gpu: bool = False, chunk: int = 32) -> tuple[int, int, bool]:
    """How to vectorize ``count`` pictures with ``options``: the worker processes (``jobs``, else
    ``plan_jobs``'s; 1 on a GPU or for the model's own paths unrefined; at most one a chunk), the
    pictures a chunk, and whether most pictures need the model (clean refined pictures up to the
    polish's size; all with the model's parts or no refinement), when torch is best imported once
    before the workers fork. Where most are refined, ``chunk`` at a time (refined together); else
    in sixteen chunks or more, for the workers to share evenly. The chunks never depend on the
    workers, so ``-j`` changes no SVG. ``sides``: the ``(W, H)`` of some of them (``None`` where
    unknown)."""
    s = options.resolve()
    side = _batch_side(s)
    batched = not s.refine and s.parts == "model"  # one forward pass: a pool only slows it down
    known = [sz or (512, 512) for sz in sides] or [(512, 512)]  # a size unknown: a 512 px picture's
    needs = [side is None or max(sz) <= side for sz in known]  # which need the model
    if jobs is None:
        jobs = 1 if gpu or batched else plan_jobs(known, needs, count, most)
    jobs = max(1, min(jobs, count))
    heavy = sum(needs) * 2 >= len(needs)  # most pictures need torch: imported once, before the fork
    if not heavy:  # most pictures traced alone: sixteen chunks or more, for the workers to share evenly
        chunk = max(1, min(chunk, -(-count // 16)))
    return min(jobs, -(-count // chunk)), chunk, heavy  # (chunks whatever the workers: the same SVGs for any -j)


def _batch_side(s: Plan) -> int | None:
    """The longest side of a picture that the refinement of plan ``s`` may batch with others (the
    polish's; 0: none is polished), or ``None`` where every picture may be (the model's own paths, or
    no refinement)."""
    return (s.max_side if s.polish else 0) if s.refine and s.parts == "clean" else None


def batch_groups(options: VectorizeOptions, sides: list[tuple[int, ...]]) -> list[list[int]]:
    """A chunk's pictures (``sides``: each one's ``(H, W)``) as the groups worth handing to workers
    apart: those the refinement may batch together (``_batch_side``) as one group, in order, and
    each other picture alone, as it is traced alone anyway. Each SVG is the one the whole chunk
    gives; a folder's large pictures (its photos) spread over the workers, not three to one."""
    side = _batch_side(options.resolve())
    if side is None:
        return [list(range(len(sides)))] if sides else []
    together = [i for i, hw in enumerate(sides) if max(hw[:2]) <= side]
    return ([together] if together else []) + [[i] for i, hw in enumerate(sides) if max(hw[:2]) > side]


def plan_jobs(sides: list[tuple[int, int]], needs: list[bool], count: int, most: int) -> int:
    """The worker processes (1: none, in this process) that vectorize ``count`` pictures soonest, of
    at most ``most``, by the cost measured above: each worker's start, and the pictures' work shared.
    ``sides``: the ``(W, H)`` of some of the pictures, taken as a sample of all; ``needs``: whether
    each of them needs the model."""
    each = [MODEL_PICTURE if m else TRACE_PICTURE + TRACE_MEGAPIXEL * s[0] * s[1] / 1e6 for s, m in zip(sides, needs)]
    work = sum(each) / len(each) * count
    start = MODEL_START if any(needs) else 0.0

    def finish(jobs: int) -> float:  # this process has its imports already; a worker pays its own
        return start + work if jobs == 1 else WORKER_START + start + work / jobs
    return min(range(1, max(1, min(most, count)) + 1), key=finish)
