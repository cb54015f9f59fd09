"""The real files of bench/wild.py (issue 69): pictures that exist as files, as their makers made
them, copied as they are (a GIF, an ICO or a palette PNG is written as a PNG of the same pixels, a
JPEG stays the JPEG it is), none of them a degradation made here and none in any shipped model's
training data (fonts: shared/data/font-packages.txt; icons: Material Design Icons; emoji: Twemoji).

Sources, all reachable offline once ``make bench-sets`` has run (Debian packages, PyPI sdists):

- **Adwaita** (Debian adwaita-icon-theme): desktop icons at 512 px, legacy icons at 48 px, symbolic
  icons at 96 and 48 px;
- **Tango** (tango-icon-theme): toolbar icons at 22 px, application icons at 32 px;
- **Oxygen** (oxygen-icon-theme): desktop icons at 256 px, 16 px icons;
- **Open Clip Art** (openclipart-png 0.18): clip art drawn at random (seed 69) among files of
  64-2048 px a side;
- **scikit-image**'s sample pictures (photos, a scanned page, text on a wall, a silhouette, a logo);
- **matplotlib**'s sample data (a photo, clip art);
- **OpenCV**'s samples/data (the opencv-python-headless 4.9.0.80 sdist): photos, logos, text, a
  newspaper sudoku, sheet music, drawings;
- **OCRmyPDF**'s test scans and documentation figures (the ocrmypdf 17.13.0 sdist): scanned pages
  (a book page, a typewritten letter, a fax line), screenshots, logos;
- **Debian documentation** (nodejs, valgrind): screenshots and plots; **Tk** and **IDLE**: logos and
  pixel icons.

Each picture has a kind (how a person would call it: icon, symbolic, toolbar, pixel, clipart, logo,
photo, page, screenshot, diagram) for the report only: im2vec is never told it. A third of the
pictures, chosen by a hash of the name, is kept aside (``aside``): reported apart, never tuned on.
"""

from __future__ import annotations

import hashlib
import io
import json
import shutil
from pathlib import Path

import numpy as np
from PIL import Image

ADWAITA, TANGO, OXYGEN = (Path("/usr/share/icons") / n for n in ("Adwaita", "Tango", "oxygen/base"))
CLIPART = Path("/usr/share/openclipart/png")
CV = "opencv-python-headless-4.9.0.80/opencv/samples/data"
OCR = "ocrmypdf-17.13.0"
CLIPART_COUNT, SEED = 16, 69

# (kind, source, path or glob:count): icon themes take the first ``count`` files of a folder, sorted
PICK = [
    ("icon", "adwaita", "512x512/devices:3"), ("icon", "adwaita", "512x512/places:2"),
    ("icon", "adwaita", "512x512/mimetypes:3"), ("icon", "adwaita", "512x512/emblems:1"),
    ("icon", "adwaita", "512x512/status:1"), ("icon", "oxygen", "256x256/apps:4"),
    ("icon", "oxygen", "256x256/devices:2"), ("icon", "adwaita", "48x48/legacy/[!s]*[!c].png:6"),
    ("icon", "tango", "32x32/apps:4"),
    ("symbolic", "adwaita", "96x96/status:3"), ("symbolic", "adwaita", "96x96/categories:3"),
    ("symbolic", "adwaita", "48x48/legacy/*symbolic*:3"),
    ("toolbar", "tango", "22x22/actions:6"),
    ("pixel", "oxygen", "16x16/apps:3"), ("pixel", "idle", "python.gif"), ("pixel", "idle", "folder.gif"),
    ("pixel", "idle", "openfolder.gif"), ("pixel", "doc", "valgrind/html/images/home.png"),
    ("logo", "skimage", "logo"), ("logo", "cv", "opencv-logo.png"), ("logo", "cv", "LinuxLogo.jpg"),
    ("logo", "cv", "WindowsLogo.jpg"), ("logo", "ocr", "docs/images/logo-square.png"),
    ("logo", "ocr", "docs/images/logo-social.png"), ("logo", "tk", "pwrdLogo200.gif"),
    ("logo", "tk", "logoLarge.gif"), ("logo", "idle", "idle_256.png"),
    ("clipart", "mpl", "Minduka_Present_Blue_Pack.png"),
    *[("photo", "skimage", n) for n in ("camera", "coins", "astronaut", "coffee", "chelsea", "rocket", "moon")],
    *[("photo", "cv", n) for n in ("HappyFish.jpg", "apple.jpg", "baboon.jpg", "building.jpg", "butterfly.jpg",
                                   "fruits.jpg", "messi5.jpg", "orange.jpg", "squirrel_cls.jpg", "starry_night.jpg",
                                   "smarties.png", "board.jpg", "home.jpg", "left01.jpg", "box.png")],
    ("photo", "mpl", "grace_hopper.jpg"),
    ("page", "skimage", "page"), ("page", "skimage", "text"), ("diagram", "ocr", "tests/resources/baiona.png"),
    ("diagram", "ocr", "tests/resources/baiona_color.jpg"), ("page", "ocr", "tests/resources/crom.png"),
    ("page", "ocr", "tests/resources/linn.png"), ("page", "ocr", "tests/resources/typewriter.png"),
    ("page", "cv", "imageTextN.png"), ("page", "cv", "imageTextR.png"), ("page", "cv", "sudoku.png"),
    ("page", "cv", "notes.png"),
    ("screenshot", "ocr", "docs/images/macos-workflow.png"), ("screenshot", "ocr", "misc/flatpak/sample_screenshot.png"),
    *[("screenshot", "doc", f"nodejs/contributing/doc_img/youtube-stream-{n}.png")
      for n in ("analytics", "share", "title-description")],
    ("screenshot", "doc", "valgrind/html/images/kcachegrind_xtree.png"),
    ("diagram", "doc", "valgrind/html/images/dh-tree.png"),
    ("diagram", "doc", "nodejs/contributing/doc_img/compare-boxplot.png"),
    ("diagram", "doc", "nodejs/contributing/doc_img/scatter-plot.png"),
    *[("diagram", "cv", n) for n in ("pic1.png", "pic3.png", "pic5.png", "cards.png", "ellipses.jpg",
                                     "detect_blob.png", "ml.png", "chessboard.png")],
    *[("diagram", "skimage", n) for n in ("horse", "clock", "colorwheel")],
]
TEXT = {"page", "screenshot"}  # scored by OCR too, where a true text is known (bench/wild_text/)


def _roots(src: Path) -> dict[str, Path]:
    import idlelib

    import matplotlib

    return {"adwaita": ADWAITA, "tango": TANGO, "oxygen": OXYGEN, "cv": src / "wild-src" / CV,
            "ocr": src / "wild-src" / OCR, "doc": Path("/usr/share/doc"), "tk": Path("/usr/share/tcltk/tk8.6/images"),
            "idle": Path(idlelib.__file__).parent / "Icons", "mpl": Path(matplotlib.get_data_path()) / "sample_data"}


def _files(root: Path, spec: str) -> list[Path]:
    if ":" not in spec:
        return [root / spec]
    where, count = spec.rsplit(":", 1)
    folder, pattern = (root / where, "*.png") if (root / where).is_dir() else (root / Path(where).parent, Path(where).name)
    return sorted(folder.glob(pattern))[: int(count)]


def _clipart() -> list[Path]:
    """``CLIPART_COUNT`` Open Clip Art files of 64-2048 px a side, drawn with ``SEED``."""
    files = sorted(CLIPART.rglob("*.png"))
    rng = np.random.default_rng(SEED)
    out = []
    for i in rng.permutation(len(files)):
        with Image.open(files[i]) as im:
            if 64 <= min(im.size) and max(im.size) <= 2048:
                out.append(files[i])
        if len(out) == CLIPART_COUNT:
            return out
    return out


def aside(name: str) -> bool:
    """A third of the pictures, by a hash of the name: reported apart and never tuned on."""
    return int(hashlib.sha1(name.encode()).hexdigest()[:8], 16) % 3 == 0


def _write(data: bytes, stem: str, out: Path) -> Path:
    """The file as it is if it is a PNG or a JPEG; else (GIF, ICO) the same pixels as a PNG."""
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        dst = out / f"{stem}.png"
    elif data[:2] == b"\xff\xd8":
        dst = out / f"{stem}.jpg"
    else:
        dst, buf = out / f"{stem}.png", io.BytesIO()
        with Image.open(io.BytesIO(data)) as im:
            im.save(buf, "PNG")
        data = buf.getvalue()
    dst.write_bytes(data)
    return dst


def make_wild(src: Path, out: Path) -> list[dict]:
    """Copy every picture of ``PICK`` and the clip art into ``out/pictures``; returns and writes
    (``out/wild.json``) a row per picture: file, kind, source, origin, aside."""
    pictures = out / "pictures"
    shutil.rmtree(pictures, ignore_errors=True)  # this script's own folder: written afresh
    pictures.mkdir(parents=True)
    roots, rows = _roots(src), []
    picks = [(k, s, f) for k, s, spec in PICK if s != "skimage" for f in _files(roots[s], spec)]
    picks += [("clipart", "openclipart", f) for f in _clipart()]
    for kind, source, path in picks:
        stem = f"{kind}-{source}-{path.stem.replace('.', '-')}"
        rows.append({"file": _write(path.read_bytes(), stem, pictures).name, "origin": str(path)})
    for kind, _, name in (p for p in PICK if p[1] == "skimage"):
        import skimage.data

        arr = getattr(skimage.data, name)()
        arr = (arr * 255).astype(np.uint8) if arr.dtype == bool else arr
        buf = io.BytesIO()
        Image.fromarray(arr).save(buf, "PNG")
        rows.append({"file": _write(buf.getvalue(), f"{kind}-skimage-{name}", pictures).name,
                     "origin": f"skimage.data.{name}()"})
    for r in rows:
        r["kind"], r["source"] = r["file"].split("-")[:2]
        r["aside"] = aside(r["file"])
    rows.sort(key=lambda r: r["file"])
    (out / "wild.json").write_text(json.dumps(rows, indent=1))
    return rows
