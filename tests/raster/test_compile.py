"""The compiled renderer agrees with the eager one (values and gradients)."""

import torch

from im2vec_cli.raster import render_paths
from tests.helpers import circle


def test_compiled_matches_eager(monkeypatch):
    torch.manual_seed(0)
    base = torch.stack([circle(0.5, 0.5, 0.3, 6), circle(0.3, 0.6, 0.2, 6)]).float()
    pts = (base + 0.02 * torch.randn_like(base))[None].repeat(2, 1, 1, 1)
    cols, dep = torch.rand(2, 2, 3), torch.randn(2, 2)
    out = {}
    for flag in ("0", "1"):
        monkeypatch.setenv("IM2VEC_COMPILE", flag)
        p = pts.clone().requires_grad_(True)
        img = render_paths(p, cols, dep, size=24, composite="soft", fill_rule="evenodd")
        img.square().sum().backward()
        out[flag] = (img.detach(), p.grad)
    assert torch.allclose(out["0"][0], out["1"][0], atol=1e-5)
    assert torch.allclose(out["0"][1], out["1"][1], atol=1e-3, rtol=1e-3)
