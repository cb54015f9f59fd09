"""The published figures agree: README's tables, the model cards and docs/RESULTS.md say the same
numbers, all written from docs/results/*.json and models/*/metrics.json (docs/figures.py)."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))

import figures  # noqa: E402 - docs/figures.py

SETS = figures.SETS


def table1() -> dict[tuple[str, str], str]:
    """docs/RESULTS.md's Table 1: (set, model) -> its recon L2 cell."""
    text = (ROOT / "docs" / "RESULTS.md").read_text()
    body = text.split("## Table 1", 1)[1].split("\n\n", 2)[1]
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in body.splitlines()[2:]]
    return {(r[0], r[1]): r[2] for r in rows}


def test_no_published_figure_is_stale():
    """Every marked block is what docs/figures.py writes from the results files now
    (``python docs/figures.py`` rewrites them; ``make results`` runs it)."""
    assert figures.stale() == []


@pytest.mark.parametrize("name", SETS)
def test_readme_the_card_and_results_md_give_one_reconstruction_figure(name):
    """The test-split reconstruction L2 of each shipped model, as RESULTS.md's Table 1 prints it, is
    the one README's two tables and the model's card print (read back from the text, not the JSON)."""
    shown = table1()[(name, "Im2Vec")]
    assert re.fullmatch(r"0\.\d{4} ± 0\.\d{4}", shown)
    readme = (ROOT / "README.md").read_text()
    models_row = next(line for line in readme.splitlines() if line.startswith(f"| `{name}`"))
    results_row = next(line for line in readme.splitlines() if line.startswith(f"| {name} | "))
    card = (ROOT / "models" / name / "README.md").read_text()
    card_row = next(line for line in card.splitlines() if line.startswith("| test-split reconstruction L2"))
    assert f"| {shown} on " in models_row
    assert results_row.split("|")[2].strip() == shown
    assert card_row.split("|")[2].strip() == shown
    vae = table1()[(name, "ImageVAE (baseline)")]
    assert card_row.split("|")[3].strip() == vae and results_row.split("|")[5].strip() == vae


@pytest.mark.parametrize("name", SETS)
def test_a_card_is_short(name):
    """A card says what the model is for, how good, its limits and how to retrain it; its history
    is docs/results/history-<set>.md."""
    card = (ROOT / "models" / name / "README.md").read_text()
    assert len(card.splitlines()) <= 150
    for section in ("## How good", "## What it keeps and loses", "## Retrain it", "## History"):
        assert section in card
    assert (ROOT / "docs" / "results" / f"history-{name}.md").is_file()


def test_a_stale_block_is_found_and_rewritten(tmp_path, monkeypatch):
    """The check can fail: a block whose figure differs from the files is listed, and ``write``
    mends it; a file without the markers is an error, not silently skipped."""
    doc = tmp_path / "doc.md"
    good = figures.results_table()
    doc.write_text("intro\n<!-- figures:results:begin -->\n| fonts | 0.9999 |\n<!-- figures:results:end -->\nend\n")
    monkeypatch.setattr(figures, "blocks", lambda: [(doc, "results", good)])
    monkeypatch.setattr(figures, "ROOT", tmp_path)
    assert figures.stale() == ["doc.md: results"]
    figures.write()
    assert figures.stale() == [] and doc.read_text().startswith("intro\n") and doc.read_text().endswith("end\n")
    assert "\n".join(good) in doc.read_text()
    with pytest.raises(KeyError):
        figures.replaced("no markers here", "results", good)
