"""The optimisers that are not torch's own: Lookahead for training, a light Adam for refinement."""

from __future__ import annotations

import torch


class Lookahead:
    """Lookahead (Zhang et al. 2019) around an inner optimiser; with RAdam this is Ranger."""

    def __init__(self, optimizer: torch.optim.Optimizer, k: int = 6, alpha: float = 0.5):
        self.optimizer, self.k, self.alpha, self.count = optimizer, k, alpha, 0
        self.slow = [p.detach().clone() for g in optimizer.param_groups for p in g["params"]]

    @property
    def param_groups(self):
        return self.optimizer.param_groups

    def zero_grad(self, set_to_none: bool = True):
        self.optimizer.zero_grad(set_to_none=set_to_none)

    @torch.no_grad()
    def step(self):
        self.optimizer.step()
        self.count += 1
        if self.count % self.k == 0:
            fast = [p for g in self.optimizer.param_groups for p in g["params"]]
            for s, f in zip(self.slow, fast):
                s.add_(f - s, alpha=self.alpha)
                f.copy_(s)

    def state_dict(self):
        return {"inner": self.optimizer.state_dict(), "slow": self.slow, "count": self.count}

    def load_state_dict(self, state):
        self.optimizer.load_state_dict(state["inner"])
        for s, v in zip(self.slow, state["slow"]):
            s.copy_(v)
        self.count = state["count"]


class Adam:
    """Adam (Kingma & Ba; torch's defaults) for the few tensors refinement optimises.

    Not ``torch.optim.Adam``: building any torch optimiser imports ``torch._dynamo`` (2 s on
    a CPU in torch 2.13), which would double the time of a one-image ``vectorize``.
    """

    def __init__(self, groups: list[dict], betas: tuple[float, float] = (0.9, 0.999), eps: float = 1e-8):
        self.groups, self.betas, self.eps, self.t = groups, betas, eps, 0
        self.state = {id(p): (torch.zeros_like(p), torch.zeros_like(p)) for g in groups for p in g["params"]}

    def zero_grad(self) -> None:
        for g in self.groups:
            for p in g["params"]:
                p.grad = None

    @torch.no_grad()
    def step(self) -> None:
        self.t += 1
        b1, b2 = self.betas
        for g in self.groups:
            for p in g["params"]:
                if p.grad is None:
                    continue
                m, v = self.state[id(p)]
                m.lerp_(p.grad, 1 - b1)
                v.mul_(b2).addcmul_(p.grad, p.grad, value=1 - b2)
                denom = (v / (1 - b2**self.t)).sqrt_().add_(self.eps)
                p.addcdiv_(m, denom, value=-g["lr"] / (1 - b1**self.t))
