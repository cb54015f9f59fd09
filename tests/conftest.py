import os

# Eager by default: the suite runs many tiny renders, where compiling would cost more than it
# saves. tests/raster/test_compile.py turns compilation on explicitly.
os.environ.setdefault("IM2VEC_COMPILE", "0")

import pytest  # noqa: E402
import torch  # noqa: E402

torch.set_num_threads(min(2, os.cpu_count() or 1))

DEJAVU = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"


@pytest.fixture(scope="session")
def dejavu():
    from fontTools.ttLib import TTFont

    if not os.path.exists(DEJAVU):
        pytest.skip("DejaVu Sans is not installed (Debian package fonts-dejavu-core)")
    return TTFont(DEJAVU)
