"""bench/ship_phase.py's count of what a phase adds (issue 37): a run resumed after one of its
phases shipped must not count that phase's steps and minutes twice."""

from bench.ship_phase import _minutes, _steps, phase_span, training_with


def _run(first_time: float, steps: range) -> list[dict]:
    return [{"event": "train", "step": s, "time": first_time + s} for s in steps]


def test_a_resumed_run_adds_only_the_steps_after_its_shipped_phase():
    events = _run(100.0, range(50, 4001, 50))
    added, mine = phase_span([{"steps": 2250, "run_started": 150.0}], events, 4000)
    assert added == 1750
    assert [e["step"] for e in mine] == list(range(2300, 4001, 50))
    assert _minutes(mine) == (4000 - 2300) / 60
    assert _steps({"steps": 4000, "steps_added": added}) == "2250 to 4000"


def test_another_run_or_an_old_entry_adds_all_its_steps():
    events = _run(100.0, range(50, 3001, 50))
    for phases in ([], [{"steps": 2250, "run_started": 999.0}], [{"steps": 2250}]):
        added, mine = phase_span(phases, events, 3000)
        assert (added, mine) == (3000, events)
    assert _steps({"steps": 3000, "steps_added": 3000}) == _steps({"steps": 3000}) == "3000"


def test_the_cards_training_summary_adds_the_phase():
    before = {"steps": 2235, "wall": "50 min", "phases": "phase 4: from the fonts model", "batch": 64}
    after = training_with(before, {"phase": 5, "steps": 4000, "steps_added": 1765, "of_steps": 4000, "minutes": 32.1})
    assert after == {"steps": 4000, "wall": "50 min + 32 min", "batch": 64, "phases": "phase 4: from the fonts model; "
                     "phase 5: the run of phase 4 resumed to 4,000 of its 4,000 steps"}
    fresh = training_with({}, {"phase": 7, "steps": 4000, "steps_added": 4000, "of_steps": 4000, "minutes": 47.1})
    assert fresh == {"steps": 4000, "wall": "47 min", "phases": "phase 7: make train-<set> from phase 6, 4,000 steps"}
