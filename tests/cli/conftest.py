import pytest

from tests.helpers import make_tiny_model


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory):
    """A tiny random model folder, one per test module."""
    return make_tiny_model(tmp_path_factory.mktemp("m") / "tiny")
