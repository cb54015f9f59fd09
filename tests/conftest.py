import os

# Eager by default: the suite runs many tiny renders, where compiling would cost more than it
# saves. tests/raster/test_compile.py turns compilation on explicitly.
os.environ.setdefault("IM2VEC_COMPILE", "0")

import pytest  # noqa: E402
import torch  # noqa: E402

torch.set_num_threads(min(2, os.cpu_count() or 1))

DEJAVU = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"


@pytest.fixture(autouse=True)
def _torch_threads_kept():
    """Each test starts with the suite's torch threads: training in process sets its own (one), and a test after
    it ran on one thread, where a batch and one image at a time round apart (test_batch's model parts: 27 vs 31)."""
    threads = torch.get_num_threads()
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="session")
def dejavu():
    from fontTools.ttLib import TTFont

    if not os.path.exists(DEJAVU):
        pytest.skip("DejaVu Sans is not installed (Debian package fonts-dejavu-core)")
    return TTFont(DEJAVU)
