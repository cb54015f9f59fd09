"""Training-step benchmark (issue "The Im2Vec model"): images/s at B=64, 64^2, P=4, k=16,
and the shipped MNIST model's 32^2, P=3, k=12 step with and without a supersampled finest
loss level (``TrainConfig.supersample``), at B=64 and at the B=32 of the 60-minute MNIST run,
and with the path decoder's first conv run over the full fused input (the reference
``_stack_unfolded`` below, as before the path code was folded into a bias), side by side.

Prints compile time apart from steady state, and a per-phase breakdown of one step.
Run: ``python bench/train.py`` (``make bench``).
"""

from __future__ import annotations

import os
import sys
import time

import torch

sys.path.insert(0, os.path.dirname(__file__))

from im2vec_cli.config import ModelConfig, TrainConfig  # noqa: E402
from im2vec_cli.model.decoder import PathDecoder  # noqa: E402
from im2vec_cli.model.losses import kl_divergence
from im2vec_cli.model.vae import Im2Vec  # noqa: E402
from im2vec_cli.optim import Lookahead  # noqa: E402
from im2vec_cli.raster import gaussian_pyramid, pyramid_l2, render_pyramid  # noqa: E402

B = 64
MNIST = ModelConfig(palette="#000000", paths=3, image_size=32, fit="pad", min_segments=8, max_segments=16)

# name: (model config, k, supersample, batch, folded first conv)
CONFIGS = {
    "default (shipped fonts model)": (ModelConfig(palette="#000000"), 16, 1, B, True),
    "lean (enc 16, dec 96x3, LSTM 64)": (ModelConfig(palette="#000000", enc_width=16, dec_width=96, dec_layers=3,
                                                     lstm_hidden=64), 16, 1, B, True),
    "mnist (32^2, P=3)": (MNIST, 12, 1, B, True),
    "mnist, supersample=4 (finest level from 128^2)": (MNIST, 12, 4, B, True),
    "mnist, supersample=4, first conv over the full fused input (before)": (MNIST, 12, 4, B, False),
    "mnist, supersample=4, B=32 (the 60-minute run)": (MNIST, 12, 4, 32, True),
}


def _stack_unfolded(stack, theta, types, code):
    """Reference for ``PathDecoder._stack``: the circular stack over ``(N, 4 + C, 3k)``."""
    n, m = theta.shape
    fused = torch.cat([torch.stack([theta.cos(), theta.sin()], 1), types.expand(n, -1, -1),
                       code.unsqueeze(-1).expand(-1, -1, m)], 1)
    return stack(fused)


def main():
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, compile={os.environ.get('IM2VEC_COMPILE', '1')}")
    folded = PathDecoder.__dict__["_stack"]  # the staticmethod object: the attribute is a plain function
    for name, (cfg, k, ss, batch, fold) in CONFIGS.items():
        print(f"== {name}")
        PathDecoder._stack = folded if fold else staticmethod(_stack_unfolded)
        measure(cfg, k, ss, batch)
    PathDecoder._stack = folded


def measure(cfg: ModelConfig, k: int, supersample: int, B: int = B):
    tcfg = TrainConfig()
    torch.manual_seed(0)
    model = Im2Vec(cfg)
    opt = Lookahead(torch.optim.RAdam(model.parameters(), lr=tcfg.lr), tcfg.lookahead_k, tcfg.lookahead_alpha)
    size = cfg.image_size
    x = (torch.rand(B, 3, size, size) > 0.7).float()
    target = gaussian_pyramid(x, cfg.levels)
    times: dict[str, float] = {}

    def step(record: bool):
        t = [time.perf_counter()]
        mu, logvar = model.encode(x)
        z = mu + torch.randn_like(mu) * (0.5 * logvar).exp()
        t.append(time.perf_counter())
        dec = model.decode(z, k)
        t.append(time.perf_counter())
        renders = render_pyramid(dec.points, dec.colors, dec.depth, size=size, levels=cfg.levels, tau=0.5,
                                 fill_rule=dec.fill_rule, shape_index=dec.shape_index, samples=cfg.samples,
                                 composite="soft", supersample=supersample)
        loss = pyramid_l2(renders, target) + 1e-5 * kl_divergence(mu, logvar)
        t.append(time.perf_counter())
        opt.zero_grad()
        loss.backward()
        t.append(time.perf_counter())
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        opt.step()
        t.append(time.perf_counter())
        if record:
            for name, a, b in zip(("encoder", "decoder", "render+loss", "backward", "optimiser"), t, t[1:]):
                times[name] = times.get(name, 0.0) + (b - a)
        return t[-1] - t[0]

    first = step(False)
    for _ in range(2):
        step(False)
    n = 10
    total = sum(step(True) for _ in range(n))
    print(f"workload: B={B}, {size}^2, P={cfg.paths}, k={k}, pyramid levels={cfg.levels}, supersample={supersample}, "
          f"decoder {cfg.dec_width}x{cfg.dec_layers}, deform={cfg.deform}")
    print(f"first step (includes torch.compile): {first:.1f} s")
    print(f"steady state: {total / n * 1e3:.0f} ms/step, {B * n / total:.0f} images/s")
    for name, v in times.items():
        print(f"  {name:<12}{v / n * 1e3:8.1f} ms  {100 * v / total:5.1f}%")


if __name__ == "__main__":
    main()
