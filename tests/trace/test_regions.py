"""The picture's regions (``trace/regions.py``): two-tone detection and the palette."""

from __future__ import annotations

import numpy as np

from im2vec_cli.trace.regions import quantize, two_tone
from tests.trace.outlines import picture


def test_two_tone_and_palette_detection():
    glyph = picture('<path d="M 10 50 L 30 8.5 L 52 50 Z"/>').permute(1, 2, 0).double().numpy()
    assert two_tone(glyph, np.ones(3)) is not None
    grey_fill = picture('<circle cx="32" cy="32" r="20" fill="#888" stroke="black" stroke-width="2"/>')
    assert two_tone(grey_fill.permute(1, 2, 0).double().numpy(), np.ones(3)) is None  # grey is a colour here
    face = picture('<circle cx="32" cy="32" r="26" fill="#fcea2b" stroke="#000" stroke-width="1.8"/>'
                   '<circle cx="24" cy="26" r="3"/><circle cx="40" cy="26" r="3"/>')
    palette, labels = quantize(face.permute(1, 2, 0).double().numpy(), None)
    assert len(palette) == 3  # white, yellow, and the thin black outline with the eyes
    assert any(np.abs(p).max() < 0.15 for p in palette)
