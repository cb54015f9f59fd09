"""bench/ship_phase.py's count of what a phase adds (issue 37): a run resumed after one of its
phases shipped must not count that phase's steps and minutes twice; and what shipping writes."""

import json

import pytest
from bench.phase_card import _minutes, _steps, card_section, phase_span, training_with
from bench.ship_phase import ship, with_config, with_path_passes


def _run(first_time: float, steps: range) -> list[dict]:
    return [{"event": "train", "step": s, "time": first_time + s} for s in steps]


def _untrained(phase: int, steps: int, test_images: int, **kind) -> dict:
    """The ship entry of a phase that trained nothing (``kind``: its keys, e.g. ``feedback``), figures unchanged."""
    figures = {"test_recon_l2": 0.02, "test_recon_l2_stderr": 0.0008, "assets_recon_l2": 0.02,
               "assets_fitted_recon_l2": 0.009}
    return {"phase": phase, "date": "2026-12-05", "commit": "abc1234", "steps": steps, "steps_added": 0,
            "of_steps": steps, "minutes": 0.0, "test_images": test_images, **kind, "before": figures, "after": figures}


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


def test_a_phase_of_feedback_passes_adds_no_steps_and_says_so_on_the_card():
    entry = {"phase": 11, "date": "2026-12-04", "commit": "abc1234", "steps": 18238, "steps_added": 0,
             "of_steps": 18238, "minutes": 0.0, "test_images": 749, "feedback": 3,
             "before": {"test_recon_l2": 0.0511, "test_recon_l2_stderr": 0.0013, "assets_recon_l2": 0.0479,
                        "assets_fitted_recon_l2": 0.0043},
             "after": {"test_recon_l2": 0.0460, "test_recon_l2_stderr": 0.0012, "assets_recon_l2": 0.0430,
                       "assets_fitted_recon_l2": 0.0042}}
    before = {"steps": 18238, "wall": "41 min + 14 min", "phases": "phase 10: make train-<set> from phase 9"}
    assert training_with(before, entry) == {**before, "phases": "phase 10: make train-<set> from phase 9; "
                                            "phase 11: 3 feedback passes at inference, no training"}
    assert _steps(entry) == "18238"  # not a resumed run
    card = card_section(entry, {"feedback": 3}, [])
    assert "No training: the weights of phase 10 with 3 render-and-compare passes" in card
    assert "| test split, 749 images: recon L2 | 0.05110 ± 0.00130 | 0.04600 ± 0.00120 |" in card
    assert "Validation" not in card


def test_a_phase_that_keeps_the_closest_pass_says_so_on_the_card_and_in_the_summary():
    entry = _untrained(16, 25738, 749, feedback=8, select=True)
    card = card_section(entry, {}, [])
    assert '(`"feedback_select": true`)' in card and "`python bench/ship_phase.py --feedback 8 --select`" in card
    assert training_with({}, entry)["phases"] == ("phase 16: 8 feedback passes at inference, the closest kept per "
                                                  "picture, no training")
    plain = card_section({**entry, "select": False}, {}, [])
    assert "feedback_select" not in plain and "--select" not in plain


def test_path_passes_alone_or_after_a_run_say_so_on_the_card(tmp_path):
    """``--path-passes N``: with no run, a phase of no training that names the count; after a run,
    the run's card section names it too; a model without a path pass is refused."""
    from im2vec_cli.config import ModelConfig

    entry = _untrained(18, 30000, 357, path_passes=3, untrained=True)
    card = card_section(entry, {}, [])
    assert "No training: the weights of phase 17. Run with 3 passes of its path pass" in card
    assert '`"path_passes": 3`' in card and "Validation" not in card
    assert training_with({"steps": 30000}, entry) == {"steps": 30000, "phases": "phase 18: 3 path passes, no training"}
    run = {**entry, "untrained": False, "steps_added": 500, "minutes": 20.0}
    trained = card_section(run, {"lr": 5e-4}, [{"event": "val", "step": 500, "time": 1.0, "val_pyramid_l2": 0.03,
                                                "val_mse": 0.02}])
    assert "Run with 3 passes of its path pass" in trained and "| 500 | 0 | 0.03 | 0.02 | – |" in trained
    raw = card_section({**run, "raw_weights": True}, {}, [{"event": "val", "step": 500, "time": 1.0,
                                                           "val_pyramid_l2": 0.03, "val_mse": 0.02, "raw_val_mse": 0.01}])
    assert "trained weights are shipped, not their EMA" in raw and "| 500 | 0 | 0.03 | 0.02 | 0.01 |" in raw
    assert "not their EMA" not in trained
    (tmp_path / "config.json").write_text(ModelConfig(path_passes=1).to_json())
    with_path_passes(tmp_path, 2)
    assert ModelConfig.load(tmp_path / "config.json").path_passes == 2
    (tmp_path / "config.json").write_text(ModelConfig().to_json())
    with pytest.raises(SystemExit, match="no path pass"):
        with_path_passes(tmp_path, 2)
    with pytest.raises(SystemExit, match="no point pass"):  # --point-passes N
        with_path_passes(tmp_path, 2, "point")
    (tmp_path / "config.json").write_text(ModelConfig(point_passes=1).to_json())
    with_path_passes(tmp_path, 8, "point")
    assert ModelConfig.load(tmp_path / "config.json").point_passes == 8


def test_shipping_names_the_commit_it_is_given_and_replaces_only_the_model_files(tmp_path):
    shipped, scratch = tmp_path / "shipped", tmp_path / "scratch"
    shipped.mkdir()
    scratch.mkdir()
    (shipped / "README.md").write_text("# card\n")
    (shipped / "segments.json").write_text("{}")
    (shipped / "config.json").write_text('{"feedback": 1}')
    (scratch / "config.json").write_text('{"feedback": 2}')
    (shipped / "latent_neighbours.json").write_text("{}")  # fitted to the replaced weights: never carried over
    (shipped / "metrics.json").write_text(json.dumps({"step": 100, "test_images": 10, "test_recon_l2": 0.02,
                                                      "training": {"steps": 100, "wall": "5 min"}}))
    figures = {"test_recon_l2": 0.02, "test_recon_l2_stderr": 0.001, "assets_recon_l2": 0.02,
               "assets_fitted_recon_l2": 0.001}
    history = tmp_path / "history.md"
    ship(None, scratch, shipped, 100, 10, figures, {**figures, "test_recon_l2": 0.01}, passes=2, commit="fdc60e9",
         history=history)
    metrics = json.loads((shipped / "metrics.json").read_text())
    assert metrics["phases"][-1]["commit"] == "fdc60e9" and metrics["test_recon_l2"] == 0.01
    assert metrics["before_phase_1"]["test_recon_l2"] == 0.02 and metrics["step"] == 100
    assert (shipped / "README.md").read_text() == "# card\n"  # the card is kept; its history grows
    assert "## Phase 1 (" in history.read_text() and "code at fdc60e9)" in history.read_text()
    assert (shipped / "config.json").read_text() == '{"feedback": 2}' and (shipped / "segments.json").is_file()
    assert not (shipped / "latent_neighbours.json").exists()


def test_a_phase_from_a_lent_gpu_names_it_in_the_cards_training_summary():
    before = {"steps": 100, "wall": "59 min", "hardware": "2 CPU cores, no GPU", "phases": "one run"}
    after = training_with(before, {"phase": 6, "steps": 7270, "steps_added": 7270, "of_steps": 7270, "minutes": 6.6,
                                   "device": "NVIDIA H200"})
    assert after == {"steps": 7370, "wall": "59 min + 7 min (GPU)",
                     "hardware": "2 CPU cores, no GPU; phase 6 on a lent NVIDIA H200",
                     "phases": "one run; phase 6: bench/device_phases.py from phase 5 on a lent NVIDIA H200, 7,270 steps"}


def test_solved_colours_say_so_on_the_card_and_only_a_layered_learned_colour_model_takes_them(tmp_path):
    """``--solve-colors``: the card and the training summary name it; ``with_config`` checks the
    config as ``ModelConfig`` does (a one-shape or palette model is refused, nothing written)."""
    from im2vec_cli.config import ConfigError, ModelConfig

    entry = _untrained(19, 30000, 357, path_passes=4, solve_colors=True, untrained=True)
    card = card_section(entry, {}, [])
    assert "No training: the weights of phase 18. Run with 4 passes" in card and '`"solve_colors": true`' in card
    assert training_with({"steps": 30000}, entry)["phases"] == ("phase 19: 4 path passes, colours solved per picture, "
                                                                "no training")
    ordered = _untrained(21, 30000, 357, solve_colors=True, solve_order=True, untrained=True)
    assert '`"solve_order": true`' in card_section(ordered, {}, []) and '"solve_order"' not in card
    assert training_with({"steps": 30000}, ordered)["phases"] == ("phase 21: colours solved per picture, the layers' "
                                                                  "order searched per picture, no training")
    (tmp_path / "config.json").write_text(ModelConfig(grouping="layers").to_json())
    with_config(tmp_path, solve_colors=True, solve_order=False)
    assert ModelConfig.load(tmp_path / "config.json").solve_colors
    with_config(tmp_path, solve_order=True)
    assert ModelConfig.load(tmp_path / "config.json").solve_order
    before = ModelConfig().to_json()
    (tmp_path / "config.json").write_text(before)
    with pytest.raises(ConfigError, match="solve_colors"):
        with_config(tmp_path, solve_colors=True)
    assert (tmp_path / "config.json").read_text() == before
