"""Reading pictures (``files.py``): every Pillow mode to ``(3, H, W)`` in [0, 1] over white."""

import numpy as np
import pytest
import torch
from PIL import Image

from im2vec_cli.files import image_to_tensor


def _over_white(img: Image.Image) -> torch.Tensor:
    """The reference: RGBA in float, alpha composited onto white."""
    arr = torch.from_numpy(np.asarray(img.convert("RGBA"), dtype=np.float32) / 255.0)
    return (arr[..., :3] * arr[..., 3:] + (1 - arr[..., 3:])).permute(2, 0, 1)


@pytest.mark.parametrize("mode", ["RGB", "L", "1", "P", "CMYK", "RGBA", "LA"])
def test_every_mode_reads_as_rgb_over_white(mode):
    """Opaque pictures take the 8-bit path (a quarter of the memory) and read exactly as the
    composited path reads them; pictures with alpha are composited onto white."""
    rng = np.random.default_rng(0)
    rgba = Image.fromarray(rng.integers(0, 256, (9, 13, 4), dtype=np.uint8), "RGBA")
    img = rgba.convert(mode) if mode != "P" else rgba.convert("RGB").quantize(16)
    got = image_to_tensor(img)
    assert got.shape == (3, 9, 13) and got.dtype == torch.float32
    assert torch.equal(got, _over_white(img))


def test_a_near_black_16_bit_picture_stays_near_black():
    """16-bit samples are scaled by 65535 whatever their values: a picture whose samples all sit
    under 256 is dark, not read as 8-bit (it came out at mean 0.51 for 0.002)."""
    import io

    from im2vec_cli.files import load_image

    buf = io.BytesIO()
    Image.fromarray(np.full((16, 16), 131, np.uint16)).save(buf, "PNG")
    assert Image.open(io.BytesIO(buf.getvalue())).mode == "I;16"
    got = load_image("dark.png", buf.getvalue())
    assert torch.allclose(got, torch.full_like(got, 131 / 65535))
