"""The settings of refinement: ``RefineSettings`` and the named efforts."""

from __future__ import annotations

from dataclasses import dataclass

from ..trace import OutlineSettings


@dataclass(frozen=True)
class RefineSettings:
    """Optimisation settings of ``refine``."""

    latent_steps: int = 10
    point_steps: int = 50
    latent_lr: float = 0.05
    point_lr: float = 1.5e-3  # normalised units per Adam step (0.1 px on a 64 px image)
    color_lr: float = 0.02
    tau_start: float = 0.8  # edge softness in input pixels, annealed during the point stage...
    tau_end: float = 0.3  # ...to about a box filter's slope, which is what cairo and the input show
    levels: int = 1  # the full-resolution L2 only. Coarse levels rendered sharp against a blurred target
    # pulled the outline off the edges (IoU@4x 0.921 with 3 levels vs 0.972 with 1, bench/vectorize.py); the
    # blurred pyramid (render_pyramid's default) neither helps nor hurts (0.9888 vs 0.9891, 12 fonts test glyphs)
    max_side: int = 128  # larger inputs are fitted at this size (then scaled back: the frame is normalised)
    patience: int = 12  # stop when the loss has not improved by min_improvement in this many steps
    min_improvement: float = 2e-3
    margin: float = 0.02  # control points may leave the canvas by this much (normalised) before a penalty
    bounds_weight: float = 10.0
    min_segment_px: float = 0.5  # segments shorter than this are pushed apart (collapsed-segment guard)
    collapse_weight: float = 1e-3
    prune_tol: float = 0.01  # drop a path whose removal raises the loss by less than this fraction
    simplify_tol: float = 0.25  # after fitting, merge segments while the outline moves less than this (input px)
    polish_steps: int = 40  # points-only steps after simplifying
    polish_samples: int = 12  # lines per cubic in the polish: merged segments are long, and too coarse a
    # polygon lets the fit bend the true curve away from the edge (IoU@4x 0.972 with the model's 4)
    tolerance: float = 0.5  # clean outlines: cubics fitted within this many input px of the traced/united ring
    outline_steps: int = 40  # clean outlines: points (and colours) polished against the input...
    outline_tau: float = 0.3  # ...from this edge softness, annealed to tau_end
    split_error: float = 0.01  # then segments along which the render is still this wrong (MSE) are halved and
    # the polish repeated (0: never)
    max_segments: int = 200  # per contour, splitting stops here
    model_start: bool = True  # clean outlines of a two-tone image: also start from the model's paths (redrawn
    # clean), keep the better start. On 40 held-out glyphs and 40 icons it changed IoU@4x by -0.0005 and 0.0000
    # at twice the time (bench/outlines.py), so the fast effort traces the image alone

    def outline_settings(self) -> OutlineSettings:
        """The settings of the clean-outline pipeline (``trace.clean_outlines``)."""
        return OutlineSettings(self.tolerance, self.split_error, self.max_segments, self.model_start,
                               polish=self.outline_steps > 0, polish_side=self.max_side)


# Named efforts (`vectorize --effort`; options.EFFORTS names them, torch-free, for the CLI).
# "best" is ``RefineSettings()``; "fast" takes about a third of the steps and a
# coarser polish polygon: on 62 held-out Liberation Sans Narrow glyphs
# at 64 px (fonts model) IoU@4x 0.9855 and MSE 0.00051 in 0.26 s per glyph, against 0.9913,
# 0.00022 and 0.79 s (on all 248 glyphs, `make bench-vectorize`: 0.9867 / 0.00036 in 0.44 s against
# 0.9914 / 0.00018 in 1.01 s; potrace 0.9524 / 0.00283), so that one `vectorize` fits in about 2 s
# with torch's import.
EFFORTS = {  # in the order of options.EFFORTS
    "draft": RefineSettings(latent_steps=0, point_steps=0, polish_steps=0, outline_steps=0, split_error=0.0,
                            model_start=False),  # clean outlines traced and fitted, not polished
    "fast": RefineSettings(latent_steps=5, point_steps=25, polish_steps=15, polish_samples=8, outline_steps=25,
                           model_start=False),
    "best": RefineSettings(split_error=0.005),
}
