"""File input and output shared by the CLI and the library: atomic writes, image loading,
PNG encoding.

Pictures are ``(H, W, 3)`` float32 arrays in [0, 1] on a white background (``load_picture``,
``as_picture``: NumPy only, so that a picture traced and not polished never imports torch), or
the same as ``(3, H, W)`` tensors (``load_image``, ``as_image``).
"""

from __future__ import annotations

import errno
import io
import os
import secrets
import stat
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
from PIL import Image, ImageOps

from .errors import Im2VecError, InputError

MAX_PIXELS = 64_000_000  # larger images are refused (decompression bombs)
MIN_SIDE = 4  # smaller images carry no shape to vectorize
MAX_INPUT_BYTES = 256 * 2**20  # larger input files (and stdin) are refused while reading: 64 MP as PNG fits
NAME_MAX = 255  # bytes in a file name (Linux, macOS, Windows)


def atomic_write(path: str | os.PathLike, data: bytes | str, *, durable: bool = True) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename, so that a crash
    never leaves a partial file behind. ``durable=False`` skips the fsync (bulk datasets).

    Only a regular file (or nothing) is replaced, keeping its mode; through a link to one,
    the file it points to is (the link stays). A character device or a FIFO (``/dev/null``,
    ``/dev/stdout``, a named pipe) is written as a stream. Anything else (a folder, a socket,
    a block device, a broken link) raises ``OSError`` naming it and is left as it was."""
    path = Path(path)
    raw = data.encode("utf-8") if isinstance(data, str) else data
    mode = None
    try:
        st = os.stat(path)  # through links
    except FileNotFoundError:
        if os.path.lexists(path):
            raise OSError(errno.ENOENT, "a broken link: not replaced", str(path)) from None
    else:
        if stat.S_ISCHR(st.st_mode) or stat.S_ISFIFO(st.st_mode):
            with open(path, "wb") as f:
                f.write(raw)
            return
        if not stat.S_ISREG(st.st_mode):
            what = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file, a device or a FIFO"
            raise OSError(errno.EEXIST, f"{what}: not replaced", str(path))
        mode = stat.S_IMODE(st.st_mode)
        if path.is_symlink():
            path = Path(os.path.realpath(path))
    directory = path.parent if str(path.parent) else Path(".")
    # ".NAME.XXXXXXXX.tmp": keep the temp name within NAME_MAX whatever the target's length
    stem = os.fsdecode(os.fsencode(path.name)[: NAME_MAX - 16])
    tmp = None
    try:
        # The name is chosen before the file exists, so that an interrupt (Ctrl-C) arriving
        # just after it is created still finds it to remove.
        while True:
            tmp = directory / f".{stem}.{secrets.token_hex(4)}.tmp"
            try:
                fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
                break
            except FileExistsError:
                tmp = None
        if mode is not None:
            os.chmod(tmp, mode)  # the file it replaces keeps its mode
        with os.fdopen(fd, "wb") as f:
            f.write(raw)
            if durable:
                f.flush()
                os.fsync(f.fileno())
        os.replace(tmp, path)
        if durable:
            _fsync_dir(directory)  # make the rename itself survive a power cut
    except BaseException:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
        raise


def holds_files(path: str | os.PathLike) -> bool:
    """Whether ``path`` exists as anything but an empty folder (an output there is someone's work)."""
    path = Path(path)
    if not os.path.lexists(path):
        return False
    if path.is_symlink() or not path.is_dir():
        return True
    return any(path.iterdir())


def check_output_folder(out_dir: str | Path, overwrite: bool, *inputs: str | Path,
                        error: type[Im2VecError] = Im2VecError) -> None:
    """Refuse (``error``) to make ``out_dir`` anew when it holds files (unless ``overwrite``) or
    holds, or is, one of ``inputs`` (a run, model or source folder the work reads)."""
    out = Path(out_dir).resolve()
    for src in inputs:
        src = Path(src).resolve()
        if src == out or out in src.parents:
            what = "is" if src == out else f"holds {src},"
            raise error(f"{out_dir}: {what} the folder this reads; write to another folder")
    if holds_files(out_dir) and not overwrite:
        raise error(f"{out_dir}: holds files; --overwrite replaces the folder whole")


def replace_folder(path: str | os.PathLike, write: Callable[[Path], object]) -> Path:
    """Make the folder ``path`` whole from ``write(tmp)``: ``write`` fills a fresh sibling
    folder, which then takes the place of whatever folder was at ``path`` (removed), so that a
    crash or an exception leaves either the old folder or the new one, never a mix.

    ``path`` must be a folder or nothing: a file, a link or anything else there raises
    ``OSError`` naming it, left as it was."""
    import shutil

    path = Path(path)
    if os.path.lexists(path) and (path.is_symlink() or not path.is_dir()):
        raise OSError(errno.EEXIST, "not a folder: not replaced", str(path))
    parent = path.parent if str(path.parent) else Path(".")
    parent.mkdir(parents=True, exist_ok=True)
    stem = os.fsdecode(os.fsencode(path.name)[: NAME_MAX - 16])
    tmp = Path(tempfile.mkdtemp(prefix=f".{stem}.", suffix=".tmp", dir=parent))
    old = None
    try:
        write(tmp)
        if os.path.lexists(path):
            old = Path(tempfile.mkdtemp(prefix=f".{stem}.", suffix=".old", dir=parent))
            os.replace(path, old)  # onto the empty folder just made: atomic on POSIX
        os.replace(tmp, path)
    except BaseException:
        if old is not None and not os.path.lexists(path):
            os.replace(old, path)  # put the old folder back
            old = None
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    finally:
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    return path


def _fsync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return  # not supported here (e.g. Windows): the data itself is already synced
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def open_image(data: bytes, name: str = "<image>", max_pixels: int = MAX_PIXELS) -> Image.Image:
    """Decode image bytes with Pillow, turning every failure into a one-line ``InputError``.

    Animated images (APNG, GIF, WebP) give their first frame; EXIF orientation is applied.
    Images smaller than ``MIN_SIDE`` or larger than ``MAX_PIXELS`` (or ``max_pixels``) are refused.
    """
    if not data:
        raise InputError(f"{name}: empty file")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # Pillow's notes on odd files (a corrupt EXIF block): the picture reads
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            img = Image.open(io.BytesIO(data))
            if img.width * img.height > MAX_PIXELS:
                raise InputError(f"{name}: image too large ({img.width}x{img.height} pixels; "
                                 f"at most {MAX_PIXELS // 1_000_000} megapixels)")
            if img.width * img.height > max_pixels:  # from the header, before decoding
                raise InputError(f"{name}: image too large for the memory budget ({img.width}x{img.height} pixels; "
                                 f"at most {max_pixels / 1e6:.1f} megapixels)")
            img.load()  # the first frame of an animation
            img = ImageOps.exif_transpose(img)
    except InputError:
        raise
    except (Image.DecompressionBombError, Image.DecompressionBombWarning) as exc:
        raise InputError(f"{name}: image too large (decompression bomb): {exc}") from None
    except MemoryError:
        raise InputError(f"{name}: not enough memory to decode this image") from None
    except Image.UnidentifiedImageError:  # its message names our in-memory buffer, not the file
        raise InputError(f"{name}: not a readable image (no image format Pillow knows, e.g. PNG or JPG)") from None
    except Exception as exc:  # noqa: BLE001 - any decoder failure on arbitrary bytes is a bad file
        raise InputError(f"{name}: not a readable image ({_one_line(exc)})") from None
    if min(img.width, img.height) < MIN_SIDE:
        raise InputError(f"{name}: image too small ({img.width}x{img.height} pixels; at least {MIN_SIDE} per side)")
    return img


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text[:200]


def image_to_array(img: Image.Image) -> np.ndarray:
    """Any Pillow mode -> ``(H, W, 3)`` float32 in [0, 1], alpha composited onto white."""
    if img.mode in ("I;16", "I;16B", "I;16L", "I;16N", "I"):
        arr = np.asarray(img, dtype=np.float64)
        # 16 bits a sample (a near-black one too); 32-bit integers say nothing of their range: by their values
        top = 65535.0 if img.mode.startswith("I;16") or arr.max() > 255 else 255.0
        return _grey((arr / top).astype(np.float32).clip(0, 1))
    if img.mode == "F":
        return _grey(np.nan_to_num(np.asarray(img, dtype=np.float32), nan=1.0, posinf=1.0, neginf=0.0).clip(0, 1))
    if img.mode in ("LAB", "HSV", "YCbCr"):
        img = img.convert("RGB")
    if "A" not in img.getbands() and "transparency" not in img.info:
        rgb = np.asarray(img.convert("RGB")).astype(np.float32)  # 8-bit to float once: no float64 temporaries
        rgb /= 255
        return rgb
    arr = np.asarray(img.convert("RGBA"), dtype=np.float32) / 255.0  # (H, W, 4)
    rgb, a = arr[..., :3], arr[..., 3:]
    return rgb * a + (1 - a)  # white background


def _grey(g: np.ndarray) -> np.ndarray:
    return np.repeat(g[..., None], 3, axis=2)


def image_to_tensor(img: Image.Image):
    """Any Pillow mode -> ``(3, H, W)`` float tensor in [0, 1], alpha composited onto white."""
    return to_tensor(image_to_array(img))


def to_tensor(picture: np.ndarray):
    """A picture ``(H, W, 3)`` -> its ``(3, H, W)`` float tensor (torch is imported here, not before)."""
    import torch

    return torch.from_numpy(picture).permute(2, 0, 1).contiguous()


def read_capped(stream, name: str, limit: int = MAX_INPUT_BYTES) -> bytes:
    """Read a binary stream to its end, refusing it (``InputError``) as soon as it passes
    ``limit`` bytes: memory stays bounded on ``/dev/zero`` or an endless pipe."""
    chunks, size = [], 0
    while True:
        chunk = stream.read(min(2**20, limit + 1 - size))
        if not chunk:
            return b"".join(chunks)
        chunks.append(chunk)
        size += len(chunk)
        if size > limit:
            raise InputError(f"{name}: more than {limit // 2**20} MiB (an image that large is refused)")


def read_file(path: str | os.PathLike, limit: int = MAX_INPUT_BYTES) -> bytes:
    """The bytes of a file (at most ``limit``); a missing, unreadable, directory or oversized
    path is a one-line ``InputError``."""
    try:
        with open(path, "rb") as f:
            return read_capped(f, str(path), limit)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None


def read_regular(path: str | os.PathLike, limit: int, what: str = "file") -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes. A FIFO, a device or a folder is
    refused without waiting on it (opened non-blocking, then checked), and so is a larger file,
    from its size before any read (a sparse file of gigabytes costs nothing): one ``InputError``."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode) or st.st_size > limit:
        os.close(fd)
        if stat.S_ISREG(st.st_mode):
            raise InputError(f"{path}: {st.st_size:,} bytes, over the {limit:,} a {what} may have")
        kind = "a folder" if stat.S_ISDIR(st.st_mode) else "a FIFO" if stat.S_ISFIFO(st.st_mode) else "not a regular file"
        raise InputError(f"{path}: {kind}, where a {what} should be")
    with os.fdopen(fd, "rb") as f:
        return read_capped(f, str(path), limit)


def load_picture(path: str | os.PathLike, data: bytes | None = None, max_pixels: int = MAX_PIXELS) -> np.ndarray:
    """Read an image file (or given bytes) as ``(H, W, 3)`` float32 in [0, 1] over white (at most
    ``max_pixels``, checked before decoding)."""
    name = str(path)
    img = open_image(read_file(path) if data is None else data, name, max_pixels)
    try:
        return image_to_array(img)
    except MemoryError:
        raise InputError(f"{name}: not enough memory to convert this image") from None
    except Exception as exc:  # noqa: BLE001 - exotic modes Pillow cannot convert
        raise InputError(f"{name}: unsupported image mode {img.mode} ({_one_line(exc)})") from None


def load_image(path: str | os.PathLike, data: bytes | None = None, max_pixels: int = MAX_PIXELS):
    """``load_picture`` as a ``(3, H, W)`` tensor."""
    return to_tensor(load_picture(path, data, max_pixels))


def encode_png(img: Image.Image) -> bytes:
    """A Pillow image -> PNG bytes."""
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    return buf.getvalue()


def tensor_to_png(img) -> bytes:
    """``(3, H, W)`` or ``(1, H, W)`` tensor in [0, 1] -> PNG bytes."""
    arr = (img.detach().float().clamp(0, 1) * 255).round().byte().cpu().numpy()
    if arr.shape[0] == 1:
        return encode_png(Image.fromarray(arr[0], "L"))
    return encode_png(Image.fromarray(arr.transpose(1, 2, 0), "RGB"))


def as_picture(image) -> np.ndarray:
    """A picture in any of the forms the Python API takes -> ``(H, W, 3)`` float32 in [0, 1] over white.

    Args:
        image: a Pillow image; a NumPy array ``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)`` (uint8 in
            [0, 255], or float in [0, 1]); a tensor ``(3, H, W)`` in [0, 1]; or a file path.
    """
    if isinstance(image, (str, os.PathLike)):
        return load_picture(image)
    if isinstance(image, Image.Image):
        out = image_to_array(image)
    elif hasattr(image, "detach") and hasattr(image, "permute"):  # a tensor (torch is not imported for this)
        if image.dim() != 3 or image.shape[0] != 3:
            raise ValueError(f"image tensor must be (3, H, W), got {tuple(image.shape)}")
        out = image.detach().float().cpu()
        if out.numel() and (out.min() < 0 or out.max() > 1):  # a copy only where one is needed
            out = out.clamp(0, 1)
        out = np.ascontiguousarray(out.permute(1, 2, 0).numpy())
    else:
        out = _array_to_picture(image)
    if min(out.shape[:2]) < MIN_SIDE:
        raise InputError(f"image too small ({out.shape[1]}x{out.shape[0]} pixels; at least {MIN_SIDE} per side)")
    return out


def as_image(image):
    """``as_picture`` as a ``(3, H, W)`` tensor."""
    return to_tensor(as_picture(image))


def _array_to_picture(image) -> np.ndarray:
    """A NumPy-like ``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)`` array -> ``(H, W, 3)`` in [0, 1]."""
    arr = np.asarray(image)
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] not in (3, 4)):
        raise ValueError(f"image array must be (H, W), (H, W, 3) or (H, W, 4), got {arr.shape}")
    if arr.dtype == np.uint8:
        arr = arr.astype(np.float32) / 255
    elif np.issubdtype(arr.dtype, np.floating):
        arr = np.nan_to_num(arr.astype(np.float32), nan=1.0, posinf=1.0, neginf=0.0).clip(0, 1)
    else:
        raise ValueError(f"image array must be uint8 or float, got {arr.dtype}")
    if arr.ndim == 2:
        return _grey(arr)
    if arr.shape[2] == 4:
        arr = arr[..., :3] * arr[..., 3:] + (1 - arr[..., 3:])  # alpha over white
    return np.ascontiguousarray(arr)
