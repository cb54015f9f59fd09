"""No crossings (``trace/untangle.py``)."""

from __future__ import annotations

import numpy as np

from im2vec_cli.trace.untangle import crosses, untangle
from im2vec_cli.vector import VectorImage, VectorShape
from tests.trace.outlines import check_clean_svg, ink


def _lines(pts):
    """A closed contour of straight cubics through ``pts``."""
    pts = np.asarray(pts, float)
    nxt = np.roll(pts, -1, 0)
    return np.concatenate([np.stack([p, p + (q - p) / 3, p + 2 * (q - p) / 3]) for p, q in zip(pts, nxt)])


def test_untangle_removes_crossings_and_keeps_the_fill():
    """A contour folded into a small loop at a corner (what a polished corner can do) is found
    crossing and replaced by its exact outline: nothing crosses, the render stays the same
    but for the loop's pin hole."""

    square = _lines([[10, 10], [50, 10], [50, 50], [10, 50]])
    looped = _lines([[10, 10], [50, 10], [51.5, 11.5], [49, 12.5], [50, 9], [50, 50], [10, 50]])  # a loop at a corner
    assert not crosses([square]) and crosses([looped])
    vec = VectorImage(64, 64, [VectorShape([looped], (0, 0, 0), "nonzero")])
    out = untangle(vec)
    assert not any(crosses(s.contours) for s in out.shapes)
    check_clean_svg(out.to_svg())
    a, b = ink(vec.to_svg(), 4), ink(out.to_svg(), 4)
    assert (a != b).sum() <= 16  # at most the loop's pin hole, a pixel at 4x
    kept = untangle(VectorImage(64, 64, [VectorShape([square])]))  # nothing to untangle: left as it was
    assert len(kept.shapes) == 1 and len(kept.shapes[0].contours) == 1
    assert (ink(kept.to_svg(), 4) != ink(VectorImage(64, 64, [VectorShape([square])]).to_svg(), 4)).sum() == 0


def test_a_shape_path_ops_fail_on_is_kept_not_a_crash(monkeypatch):
    """Skia's path ops can fail (PathOpsError: nearly coincident curves in a scanned page): the
    crossing shape is then kept as it is, and the picture still gets its SVG."""
    import pathops

    looped = VectorShape([_lines([[10, 10], [50, 10], [51.5, 11.5], [49, 12.5], [50, 9], [50, 50], [10, 50]])],
                         (0, 0, 0), "nonzero")

    def fail(*a, **k):
        raise pathops.PathOpsError("operation did not succeed")

    monkeypatch.setattr(pathops, "simplify", fail)
    out = untangle(VectorImage(64, 64, [looped]))
    assert len(out.shapes) == 1 and np.array_equal(out.shapes[0].contours[0], looped.contours[0])
