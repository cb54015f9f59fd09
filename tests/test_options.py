"""options.py: what the user chose (``VectorizeOptions``) resolved into one ``Plan`` that every stage
reads; the notes on options that do nothing; the fields a fine-tune cannot change."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from im2vec_cli import api
from im2vec_cli.errors import ConfigError, OptionWarning
from im2vec_cli.options import EFFORT_SETTINGS, EFFORTS, GROWABLE, Plan, VectorizeOptions, effort_plan, fixed_on_init


def test_the_plan_is_the_effort_with_the_users_choices():
    """Each effort's plan differs from ``Plan()`` where ``EFFORT_SETTINGS`` says, and nowhere else;
    a tolerance or simplify_px given replaces the effort's, and the rest of the choices travel as they are."""
    assert tuple(EFFORT_SETTINGS) == EFFORTS
    for effort, fields in EFFORT_SETTINGS.items():
        plan = VectorizeOptions(effort=effort).resolve()
        differ = {f.name for f in dataclasses.fields(Plan) if getattr(plan, f.name) != getattr(Plan(), f.name)}
        assert differ == set(fields)
        assert plan == effort_plan(effort)
    plan = VectorizeOptions(tolerance=2, colors=3, max_paths=7, preset="scan", speckle=4, max_memory=2**30).resolve()
    assert (plan.tolerance, plan.colors, plan.max_paths, plan.preset, plan.speckle) == (2.0, 3, 7, "scan", 4)
    assert plan.work_pixels == VectorizeOptions(max_memory=2**30).work_pixels() < Plan().work_pixels
    assert VectorizeOptions().resolve().preset is None  # auto: the kind it looks like
    assert VectorizeOptions(simplify_px=1.5).resolve().simplify_tol == 1.5
    assert VectorizeOptions().resolve().simplify_tol == Plan().simplify_tol  # refinement's own default
    assert VectorizeOptions(refine=False).resolve().simplify_tol == 0.0  # nothing merged unless asked


def test_the_draft_effort_polishes_nothing():
    assert not effort_plan("draft").polish and effort_plan("fast").polish and Plan().polish


def test_every_default_tolerance_is_the_plans():
    """The tolerance's default is written once: no effort, option or stage sets another."""
    assert VectorizeOptions().tolerance is None
    assert all("tolerance" not in fields for fields in EFFORT_SETTINGS.values())
    assert {VectorizeOptions(effort=e).resolve().tolerance for e in EFFORTS} == {Plan().tolerance}


@pytest.mark.parametrize("fields, idle", [
    ({"refine": False, "tolerance": 2, "colors": 3, "effort": "best"}, {"tolerance", "colors", "effort"}),
    ({"parts": "model", "tolerance": 2, "preset": "scan"}, {"tolerance", "preset"}),
    ({"quality": 0.01}, {"quality"}),
    ({"segments": "auto", "quality": 0.01, "tolerance": 2, "colors": 3}, set()),
])
def test_options_that_do_nothing_are_noted_and_the_api_warns_of_them(fields, idle):
    options = VectorizeOptions(**fields)
    notes = options.idle(set(fields))
    assert {n.split()[0] for n in notes} == idle and all("does nothing here: " in n for n in notes)
    model = api.ModelRef(load=lambda: pytest.fail("a 300 px picture is traced alone"))
    picture = np.ones((300, 300, 3))
    picture[100:200, 120:180] = 0.0
    if not fields.get("refine", True) or fields.get("parts") == "model" or "segments" in fields:
        return  # those need the model: the same warning, checked below without it
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        api.vectorize(picture, model, **fields)
    assert {str(w.message).split()[0] for w in caught if w.category is OptionWarning} == idle


def test_the_api_warns_once_of_an_option_the_mode_ignores():
    """``vectorize(..., refine=False, tolerance=2)``: an ``OptionWarning`` naming tolerance (the model's
    guess has no tolerance), before any work; an ``errors.ConfigError`` for a bad value, as before."""
    model = api.ModelRef(load=lambda: (_ for _ in ()).throw(RuntimeError("stop here")))
    with warnings.catch_warnings(record=True) as caught, pytest.raises(RuntimeError, match="stop here"):
        warnings.simplefilter("always")
        api.vectorize(np.ones((8, 8, 3)), model, refine=False, tolerance=2.0)
    assert [str(w.message).split()[0] for w in caught if w.category is OptionWarning] == ["tolerance"]
    with pytest.raises(ConfigError, match="tolerance"):
        api.vectorize(np.ones((8, 8, 3)), model, tolerance=-1)


def test_a_fine_tune_may_change_only_the_growable_fields():
    start = {"paths": 4, "latent": 128, "grouping": "evenodd"}
    assert fixed_on_init({"paths": 8, "grouping": "nonzero"}, start) == []
    assert fixed_on_init({"latent": 128}, start) == []  # the model's own value: nothing changes
    assert fixed_on_init({"latent": 64, "image_size": 32, "paths": 8}, start) == ["image_size", "latent"]
    assert "paths" in GROWABLE and "latent" not in GROWABLE
