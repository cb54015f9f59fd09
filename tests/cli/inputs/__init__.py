"""The bad-input cases' builders, one module per command (``test_bad_input.py`` runs them)."""
