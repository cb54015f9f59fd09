"""Progress events (``events.py``): typed for callers, and the same JSON records in
``RUN/metrics.jsonl`` as the dicts they replaced."""

import json

from im2vec_cli.events import NonFinite, Skipped, TrainStep, Validated


def test_records_spread_figures_in_place_and_keep_the_field_order():
    step = TrainStep(7, {"loss": 0.5, "k": 6}, img_per_s=120.0, time=1.5)
    assert list(step.as_dict().items()) == [("event", "train"), ("step", 7), ("loss", 0.5), ("k", 6),
                                            ("img_per_s", 120.0), ("time", 1.5)]
    val = Validated(9, {"val_pyramid_l2": 0.01, "val_mse": 0.02}, time=2.0)
    assert val.as_dict() == {"event": "val", "step": 9, "val_pyramid_l2": 0.01, "val_mse": 0.02, "time": 2.0}
    bad = NonFinite(3, float("nan"), float("inf"), 1, 0.0)
    assert list(bad.as_dict()) == ["event", "step", "loss", "grad_norm", "in_a_row", "time"]
    assert json.loads(json.dumps(Skipped("a.png: not an image").as_dict())) == {"event": "skip",
                                                                                 "message": "a.png: not an image"}


def test_events_match_by_class():
    seen = []
    for e in (Skipped("x"), TrainStep(2, {"loss": 1.0}), Validated(2)):
        match e:
            case TrainStep(step=s, figures={"loss": loss}):
                seen.append(("train", s, loss))
            case Skipped(message=m):
                seen.append(("skip", m))
            case _:
                seen.append(e.kind)
    assert seen == [("skip", "x"), ("train", 2, 1.0), "val"]
