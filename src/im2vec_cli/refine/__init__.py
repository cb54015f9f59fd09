"""Test-time refinement: fit the decoded paths of one image to that image.

The amortised encoder gives a first guess; refinement then minimises the pyramid L2
(sec. 3.4, eq. 1) against the input itself, first over the latent ``z`` (the shapes stay
on the model's manifold), then over the control points and colours directly. Paths whose
removal barely changes the loss are then dropped, neighbouring segments are merged while the
outline moves less than ``simplify_tol`` pixels (``trace/simplify.py``), and a short points-only
polish follows. The default uses one pyramid level: see ``options.Plan.levels``. The stages
are the methods of ``Refinement``; overlapping even-odd paths are resolved once, on the
latent stage's result (``vector.resolve_overlaps``), and the later stages fit under the rule it chose.

Frames: the model decodes in its square frame (``frame.Placement``). Refinement works in
the *input's* normalised frame, ``(x / W, y / H)`` of the input's pixel grid, and renders at
the input's resolution (inputs larger than ``max_side`` are fitted at a reduced copy), so
``tau`` is measured in input pixels.

Its settings are the run's ``options.Plan`` (``options.EFFORT_SETTINGS`` names the efforts). Its
names load on first use (``lazy.py``).
"""

from ..lazy import lazy_names
from ..options import PARTS

_WHERE = {
    "REFINE_BATCH": "batch",
    "clean_outlines": "clean",
    "model_paths": "stages",
    "trace_alone": "clean",
    "Refinement": "stages",
    "refine": "batch",
    "refine_batch": "batch",
}
__all__ = ["PARTS", *sorted(_WHERE)]
__getattr__, __dir__ = lazy_names(__name__, _WHERE)
