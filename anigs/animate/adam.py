"""Adam with an exponential learning-rate decay, without ``torch.optim``.

The update stage trains a few small tensors for about a hundred steps, so the process's start-up
matters: the first ``torch.optim`` optimizer a process builds imports ``torch._dynamo``, 2.7 s of
CPU (measured on the demo's update job, ``python -m cProfile``; the whole training is 13 s). This
is the same arithmetic as ``torch.optim.Adam`` (its single-tensor path, which it takes on the CPU;
amsgrad, weight decay and maximize off) followed by ``torch.optim.lr_scheduler.ExponentialLR``, op
for op, so on the CPU the parameters come out bit for bit the same (``tests/animate/test_adam.py``).
"""
from __future__ import annotations

from collections.abc import Iterable

import torch


class Adam:
    """Adam over parameter groups ``[{"params": [Tensor, ...], "lr": float, ...}]`` (other keys kept).

    ``step()`` applies one Adam update to every parameter that has a gradient, then multiplies
    every group's ``lr`` by ``gamma`` (``ExponentialLR``; ``gamma=1`` keeps it constant).
    """

    def __init__(self, groups: Iterable[dict], betas: tuple[float, float] = (0.9, 0.999), eps: float = 1e-8,
                 gamma: float = 1.0):
        self.param_groups = [dict(g, params=list(g["params"])) for g in groups]
        if not self.param_groups:
            raise ValueError("Adam: no parameter groups")
        for g in self.param_groups:
            if not g["lr"] >= 0:
                raise ValueError(f"Adam: invalid learning rate {g['lr']} in group {g.get('name', '?')!r}")
        self.betas, self.eps, self.gamma = (float(betas[0]), float(betas[1])), float(eps), float(gamma)
        self.state: dict[torch.Tensor, dict[str, torch.Tensor]] = {}

    def zero_grad(self) -> None:
        """Drop every parameter's gradient (``set_to_none``)."""
        for g in self.param_groups:
            for p in g["params"]:
                p.grad = None

    @torch.no_grad()
    def step(self) -> None:
        beta1, beta2 = self.betas
        for g in self.param_groups:
            lr = g["lr"]
            for p in g["params"]:
                if p.grad is None:
                    continue
                st = self.state.get(p)
                if st is None:
                    st = self.state[p] = {"step": torch.tensor(0.0),
                                          "exp_avg": torch.zeros_like(p, memory_format=torch.preserve_format),
                                          "exp_avg_sq": torch.zeros_like(p, memory_format=torch.preserve_format)}
                grad, exp_avg, exp_avg_sq = p.grad, st["exp_avg"], st["exp_avg_sq"]
                st["step"] += 1
                exp_avg.lerp_(grad, 1 - beta1)
                exp_avg_sq.mul_(beta2).addcmul_(grad, grad, value=1 - beta2)
                step = st["step"].item()
                bias_correction1 = 1 - beta1**step
                bias_correction2 = 1 - beta2**step
                step_size = lr / bias_correction1
                denom = (exp_avg_sq.sqrt() / bias_correction2**0.5).add_(self.eps)
                p.addcdiv_(exp_avg, denom, value=-step_size)
        for g in self.param_groups:
            g["lr"] = g["lr"] * self.gamma
