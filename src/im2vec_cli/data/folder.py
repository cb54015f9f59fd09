"""Image folders for training: every PNG/JPG under a root, loaded into memory.

Images are composited onto white, converted to RGB and fitted to ``size x size``
(``fit_square``: padded with white to a square, then resized), stored as uint8 ``(N, 3, S, S)``.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import DataError, InputError
from ..files import load_image

if TYPE_CHECKING:  # torch is imported where a folder is loaded: `vectorize` lists folders without it
    import torch

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


def list_images(root: str | Path, on_skip: Callable[[str], None] | None = None) -> list[Path]:
    """Every PNG/JPG file under ``root`` (searched recursively), sorted. A name with an image
    suffix that is not a regular file (a FIFO, a device, a socket, a broken link) is left out
    and told to ``on_skip``; folders are searched."""
    root = Path(root)
    if not root.is_dir():
        raise DataError(f"{root}: not a directory")
    found = []
    for p in sorted(root.rglob("*")):
        if p.suffix.lower() not in IMAGE_SUFFIXES or p.is_dir():
            continue
        if p.is_file():
            found.append(p)
        elif on_skip is not None:
            on_skip(f"{p}: {'a broken link' if p.is_symlink() and not p.exists() else 'not a regular file'}")
    return found


def load_folder(
    root: str | Path, size: int, *, fit: str = "resize", workers: int = 2,
    on_skip: Callable[[str], None] | None = None,
) -> tuple[torch.Tensor, list[str]]:
    """Load every image under ``root``, fitted to ``size`` by ``fit_square(..., fit)``.

    Unreadable files are skipped and reported through ``on_skip`` (one line each).

    Returns:
        ``(N, 3, size, size)`` uint8 and the relative file names.
    """
    import torch

    from ..frame import fit_square

    files = list_images(root, on_skip)
    if not files:
        raise DataError(f"{root}: no images (.png, .jpg) found")

    def one(p):
        try:
            return fit_square(load_image(p), size, fit)
        except InputError as exc:
            if on_skip:
                on_skip(str(exc))
            return None

    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        imgs = list(pool.map(one, files))
    keep = [(f, i) for f, i in zip(files, imgs) if i is not None]
    if not keep:
        raise DataError(f"{root}: none of the {len(files)} image files could be read")
    data = torch.stack([(i * 255).round().to(torch.uint8) for _, i in keep])
    return data, [str(f.relative_to(root)) for f, _ in keep]


def split_indices(names: list[str], val_fraction: float) -> tuple[list[int], list[int]]:
    """Deterministic train/val split by a hash of each file's folder (so one font family or
    class folder stays on one side); single-folder sets are split by file name."""
    keys = [str(Path(n).parent) for n in names]
    if len(set(keys)) < 10:
        keys = names
    val = [i for i, k in enumerate(keys) if hash_unit(k) < val_fraction]
    if not val and len(names) > 1:
        val = [len(names) - 1]
    vs = set(val)
    return [i for i in range(len(names)) if i not in vs], val


def hash_unit(key: str) -> float:
    """A stable pseudo-random number in [0, 1] for ``key`` (SHA-256): the basis of every split."""
    return int(hashlib.sha256(key.encode()).hexdigest()[:8], 16) / 0xFFFFFFFF


def find_split_dirs(data_dir: Path) -> tuple[Path, Path | None]:
    """``DATA/train`` and ``DATA/val`` when the folder was built by ``im2vec data``."""
    if (data_dir / "train").is_dir() and (data_dir / "val").is_dir():
        return data_dir / "train", data_dir / "val"
    return data_dir, None


def split_dir(root: str | Path, split: str) -> Path:
    """``root/split`` when that folder exists (a dataset made by ``im2vec data``), else ``root``."""
    root = Path(root)
    return root / split if (root / split).is_dir() else root



LABEL_KEYS = {"file": lambda n: Path(n).stem, "folder": lambda n: Path(n).parent.name}


def folder_labels(names: list[str], key: str | None = None, max_classes: int = 1000
                  ) -> tuple[list[str], str] | None:
    """The class of each of a dataset's files (relative names), where its layout names one:
    the file name when the same names recur in every folder (fonts: ``<family>/<char>.png``),
    else the folder (MNIST: ``<digit>/<index>.png``); ``None`` when neither gives between 2 and
    ``max_classes`` classes with ten files each on average (emoji, icons). ``key`` (``"file"`` or
    ``"folder"``) forces the rule, e.g. the one the training split used.

    Returns:
        the class name of every file, and the key used.
    """
    for k in [key] if key else list(LABEL_KEYS):
        keys = [LABEL_KEYS[k](n) for n in names]
        n_classes = len(set(keys))
        if key or 2 <= n_classes <= max_classes and n_classes * 10 <= len(names):
            return keys, k
    return None
