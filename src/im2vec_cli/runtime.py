"""Device resolution, the process group of a distributed run, CPU threads, seeding and progress bars."""

from __future__ import annotations

import contextlib
import gc
import os
import random
import re
import sys
import time

import numpy as np

from .errors import Im2VecError

DEVICE_NAME = re.compile(r"auto|(cpu|mps|cuda)(:\d+)?")


def check_device(spec) -> None:
    """``Im2VecError`` for a device name ``resolve_device`` would refuse whatever the machine
    (told without importing torch); a ``torch.device`` passes."""
    if isinstance(spec, str) and not DEVICE_NAME.fullmatch(spec):
        raise Im2VecError(f"unknown device {spec!r} (use auto, cpu, cuda[:N] or mps)")


def resolve_device(spec: str = "auto"):
    """``auto`` -> CUDA if present, then MPS, else CPU; otherwise validate ``cpu|cuda[:N]|mps``."""
    import torch

    torch_ready()
    if spec == "auto":
        if torch.cuda.is_available():
            return torch.device("cuda")
        if getattr(torch.backends, "mps", None) is not None and torch.backends.mps.is_available():
            return torch.device("mps")
        return torch.device("cpu")
    try:
        dev = torch.device(spec)
    except (RuntimeError, ValueError):
        raise Im2VecError(f"unknown device {spec!r} (use auto, cpu, cuda[:N] or mps)") from None
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise Im2VecError(f"device {spec!r} asked for but CUDA is not available")
    if dev.type == "cuda" and dev.index is not None and dev.index >= torch.cuda.device_count():
        raise Im2VecError(f"device {spec!r} does not exist ({torch.cuda.device_count()} CUDA devices)")
    if dev.type == "mps" and not (getattr(torch.backends, "mps", None) and torch.backends.mps.is_available()):
        raise Im2VecError("device 'mps' asked for but MPS is not available")
    if dev.type not in ("cpu", "cuda", "mps"):
        raise Im2VecError(f"unknown device {spec!r} (use auto, cpu, cuda[:N] or mps)")
    return dev


def cpu_cores() -> int:
    """The CPU cores this process may run on."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


def free_cores(samples: int = 3, interval: float = 0.01) -> int:
    """The cores not busy with other programs (at least 1): the cores less the other tasks
    running now (``/proc/loadavg``'s count of runnable tasks, less this process's own threads
    that run: NumPy's BLAS threads spin a moment after its import, and read as a busy core;
    the fewest of ``samples`` readings ``interval`` s apart, so that a task passing through
    does not count; elsewhere the one-minute load average)."""
    cores = cpu_cores()
    try:
        running = []
        for i in range(samples):
            if i:
                time.sleep(interval)
            with open("/proc/loadavg") as f:
                running.append(int(f.read().split()[3].split("/")[0]) - _own_running())
        others = min(running)
    except (OSError, ValueError, IndexError):
        try:
            others = round(os.getloadavg()[0])
        except (OSError, AttributeError):
            others = 0
    return max(1, min(cores, cores - others))


def _own_running() -> int:
    """This process's threads that are running or runnable now (at least 1: the one asking)."""
    count = 0
    for task in os.listdir("/proc/self/task"):
        try:
            with open(f"/proc/self/task/{task}/stat") as f:
                count += f.read().rsplit(")", 1)[1].split()[0] == "R"
        except OSError:  # ended meanwhile
            continue
    return max(1, count)


def intra_op_threads(pictures: int, jobs: int = 1, free: int | None = None) -> int:
    """Torch threads for each of ``jobs`` processes refining ``pictures`` pictures in all, with
    ``free`` cores (default ``free_cores()``; take it before torch has run anything, as its
    idle threads spin for a while and count as busy).

    One picture gets one thread: its renders are at most ``options.Plan.max_side`` px, too
    small to share, and a second thread's spin-waits at every op cost 4x when another program
    holds the other core (bench/cli.py). Several share the free cores among the jobs, so
    that no more threads run than there are cores to run them.
    """
    if pictures <= 1:
        return 1
    return max(1, (free_cores() if free is None else free) // max(1, jobs))


_PENDING: dict = {}  # what set_threads and seed_everything leave for torch until it is imported


def set_threads(n: int) -> None:
    """Run torch's CPU ops on ``n`` threads, unless ``OMP_NUM_THREADS`` says how many (now if torch
    is imported, else when it is: ``torch_ready``)."""
    if not os.environ.get("OMP_NUM_THREADS"):
        _PENDING["threads"] = max(1, n)
        _apply_if_imported()


def seed_everything(seed: int) -> None:
    """Seed Python, NumPy and torch (all devices; torch now if it is imported, else when it is)."""
    random.seed(seed)
    np.random.seed(seed % 2**32)
    _PENDING["seed"] = seed
    _apply_if_imported()


def _apply_if_imported() -> None:
    if "torch" in sys.modules:
        torch_ready()


def torch_ready() -> None:
    """Give torch the threads and seed asked for before it was imported (``set_threads``,
    ``seed_everything``): whatever is about to compute with torch calls this first (loading a
    model does, through ``resolve_device``)."""
    import torch

    if "threads" in _PENDING:
        torch.set_num_threads(_PENDING.pop("threads"))
    if "seed" in _PENDING:
        torch.manual_seed(_PENDING.pop("seed"))


class _Hidden:
    """What ``progress`` gives when no bar shows: the iterable, a bar's count (``n``) and
    ``disable``, and every other call of a tqdm bar doing nothing."""

    disable = True

    def __init__(self, iterable=None):
        self.iterable, self.n = iterable, 0

    def __iter__(self):
        return iter(self.iterable)

    def update(self, n=1):
        self.n += n

    def __getattr__(self, name):  # clear, close, set_postfix, set_postfix_str, refresh, ...
        return lambda *args, **kwargs: None


def progress(iterable=None, **kwargs):
    """A tqdm bar on stderr that hides itself when stderr is not a terminal (``disable=None``:
    the same). A hidden bar does not import tqdm (22 ms of a traced picture's call)."""
    if kwargs.get("disable") is None:
        kwargs["disable"] = not sys.stderr.isatty()
    if kwargs["disable"]:
        return _Hidden(iterable)
    from tqdm.auto import tqdm

    kwargs.setdefault("file", sys.stderr)
    kwargs.setdefault("dynamic_ncols", True)
    return tqdm(iterable, **kwargs)


def setup_distributed(device):
    """Under ``torchrun`` (``WORLD_SIZE`` > 1) join the process group (gloo on CPU, nccl on
    CUDA, one GPU per local rank). Returns the device, the rank and the world size."""
    import torch
    import torch.distributed as dist

    if int(os.environ.get("WORLD_SIZE", "1")) > 1 and not dist.is_initialized():
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")
        if device.type == "cuda":
            device = torch.device("cuda", int(os.environ.get("LOCAL_RANK", "0")))
            torch.cuda.set_device(device)
    if dist.is_available() and dist.is_initialized():
        return device, dist.get_rank(), dist.get_world_size()
    return device, 0, 1


class HeldSignals:
    """Ctrl-C and SIGTERM held while a step runs, delivered between steps (``deliver()``), so that
    a run interrupted mid-step checkpoints the last whole step and resumes exactly (Ctrl-C at step
    247 left the generator a batch ahead of the weights: the resumed run ended 0.065 away). A
    second signal while one is held is delivered at once. Installed only in the main thread, and
    only over handlers that are Python functions (Ctrl-C's, the CLI's SIGTERM); elsewhere a no-op."""

    def __init__(self):
        import signal
        import threading

        self.held: list[int] = []
        self.before: dict = {}
        if threading.current_thread() is threading.main_thread():
            for signum in (signal.SIGINT, signal.SIGTERM):
                if callable(signal.getsignal(signum)):
                    self.before[signum] = signal.signal(signum, self._hold)

    def _hold(self, signum, frame):
        if self.held:  # asked twice: now
            self.before[signum](signum, frame)
        self.held.append(signum)

    def deliver(self) -> None:
        """Raise what the held signal's own handler raises (``KeyboardInterrupt``, the CLI's ``Terminated``)."""
        if self.held:
            signum = self.held.pop(0)
            self.before[signum](signum, None)

    def __enter__(self) -> HeldSignals:
        return self

    def __exit__(self, kind, *exc) -> None:
        """The handlers put back; a signal still held is delivered as the block ends (unless it
        ends by an exception)."""
        import signal

        for signum, handler in self.before.items():
            signal.signal(signum, handler)
        if kind is None:
            self.deliver()


def gpu_likely(spec: str) -> bool:
    """Whether the device ``spec`` may be a GPU, told without importing torch: ``cuda`` or ``mps``
    named, or ``auto`` where an NVIDIA driver is loaded or on macOS (MPS)."""
    if spec == "cpu":
        return False
    if spec != "auto":
        return True
    return os.path.exists("/proc/driver/nvidia/version") or sys.platform == "darwin"


@contextlib.contextmanager
def collector_paused():
    """Imports and model loading without the cyclic garbage collector, whose passes over the
    millions of objects that torch and the model allocate, and that live as long as the
    process, cost 0.2-0.3 s of a one-picture `vectorize` (bench/cli.py); those objects are
    then frozen out of later collections (``gc.freeze``), and collection goes on as before."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        if was:
            gc.enable()
