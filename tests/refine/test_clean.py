"""refine/clean.py: the clean-outline stage list, with a refinement and without one (NumPy only)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from im2vec_cli.options import Plan
from im2vec_cli.refine.clean import clean_outlines, trace_alone
from im2vec_cli.trace import read
from im2vec_cli.vector import rasterize_svg
from tests.trace.test_read import drawing, iou


class NoRenderer:
    def loss(self, vecs, index):
        raise AssertionError("a draft renders nothing")

    def polish_outline(self, vecs, flags, index):
        raise AssertionError("a draft polishes nothing")


def test_a_draft_traces_and_fits_without_rendering():
    clean = drawing(64)
    (vec, info), = clean_outlines([clean], NoRenderer(), Plan(outline_steps=0))
    back = rasterize_svg(vec.to_svg(), 64, 64)
    assert iou(back.mean(-1) < 0.5, clean.mean(-1) < 0.5) > 0.95 and info["loss_end"] is None


def test_a_picture_to_polish_needs_a_refinement():
    with pytest.raises(ValueError, match="needs a refinement"):
        clean_outlines([drawing(64)], None, Plan())  # 64 px, polished by default
    (vec, info), = trace_alone([read(drawing(200))], [(400, 400)], Plan())  # 200 px: not polished
    assert (vec.width, vec.height) == (400.0, 400.0) and vec.shapes and info["kind"] and info["loss_end"] is None


def test_the_stage_list_without_a_renderer_imports_no_torch():
    code = ("import sys, numpy as np; from im2vec_cli.refine.clean import trace_alone; from im2vec_cli.trace import read;"
            "from im2vec_cli.options import Plan; p = np.ones((300, 300, 3)); p[100:200, 80:220] = 0;"
            "v, _ = trace_alone([read(p)], [(300, 300)], Plan())[0]; assert v.shapes; print('torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
