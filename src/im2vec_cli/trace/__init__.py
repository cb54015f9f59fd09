"""Clean outlines: a picture's regions traced, rings fitted with few cubics, outlines made
clean (united, corrected, untangled): the stages, in NumPy, that ``refine.clean`` runs as its
stage list (polishing through the renderer where a picture is polished), after ``read`` (what
kind of picture it is and the clean picture it shows: scans flattened and cleaned, pixel art at
one pixel a block). Bottom up:

- ``palette``: a multi-colour picture's colours and each pixel's label (a hard-edged
  picture's exact colours, else a quantised palette, specks absorbed);
- ``regions``: the picture's flat-colour regions as polygons (two-tone: one sub-pixel level
  set; multi-colour: stacked regions; hard-edged: along the pixel edges), bounded in number;
- ``pixels``: pixel art's exact outlines (the union of its pixel squares), bounded by corner touches;
- ``fit``: rings to closed cubics within a tolerance, corners kept sharp (``Corners`` flags);
- ``simplify``: fewer segments for the same outline (neighbours merged within a tolerance), or more
  (``split_segments``);
- ``outline``: ``traced`` (the picture's regions fitted), ``redrawn`` (any vector image
  rendered, traced and fitted again: overlaps united, seams closed) and ``cleaned``;
- ``untangle``: crossings removed with Skia's path ops;
- ``pipeline``: the starts, which pictures are polished, splits where still wrong, the finish;
- ``batch``: a batch read, flat pictures, which pictures need the renderer.

Frame: the pixel frame of the picture (``vector/image.py``).
"""

from .batch import FLAT_SUMMARY, flat_result, needs_renderer, read_pictures
from .fit import Corners, fit_ring, fit_rings
from .outline import cleaned, redrawn, traced
from .pipeline import (
    CHOICE_TOLERANCE,
    Start,
    finished,
    image_starts,
    model_start_wanted,
    polished,
    split_where_wrong,
)
from .read import KINDS, Reading, read
from .regions import Region, background_color, level_polygons, trace, two_tone
from .simplify import simplify, simplify_contour, split_segments
from .untangle import crosses, untangle

__all__ = [
    "CHOICE_TOLERANCE", "Corners", "FLAT_SUMMARY", "KINDS", "Reading", "Region", "Start", "read", "background_color",
    "cleaned", "crosses", "finished", "fit_ring", "fit_rings", "flat_result", "image_starts", "level_polygons",
    "model_start_wanted", "needs_renderer", "polished", "read_pictures", "redrawn", "simplify", "simplify_contour",
    "split_segments", "split_where_wrong", "trace", "traced", "two_tone", "untangle",
]
