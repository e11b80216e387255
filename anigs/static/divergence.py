"""Divergence of the static fit: a non-finite loss or gradient, found without a host read per
step (:class:`DivergenceGuard`), reported with its iteration and the last good checkpoint."""
from __future__ import annotations

from typing import Any, Callable, Sequence

import torch


class FitDivergedError(RuntimeError):
    """The loss or a gradient became non-finite during the fit."""


class DivergenceGuard:
    """Non-finite loss or gradient detection without a host read per step.

    :meth:`record` (after ``loss.backward()``) sums every gradient (a non-finite entry makes
    its sum non-finite; so does a sum beyond float range, itself a divergence) and keeps, on
    the device, the first iteration where the loss or a sum was not finite, which of them, and
    the loss. With a fused Adam that step is skipped by the optimizer itself (``found_inf``),
    so the parameters stay finite until :meth:`check` reads the record and raises; with any
    other optimizer :meth:`record` checks at once (a host read per step).
    """

    def __init__(self, optimizer: torch.optim.Optimizer, names: Sequence[str], device: torch.device,
                 on_failure: Callable[[int, str], None] | None = None):
        self.names = list(names)
        self.on_failure = on_failure  # (iteration, what) -> raises; default FitDivergedError
        self.deferred = bool(optimizer.defaults.get("fused"))
        self.found_inf = torch.zeros((), device=device)
        self.first_bad = torch.zeros((), dtype=torch.long, device=device)  # 0: none yet
        self.bad = torch.zeros(len(self.names) + 1, dtype=torch.bool, device=device)  # [loss, *params]
        self.loss = torch.zeros((), device=device)
        if self.deferred:
            optimizer.found_inf = self.found_inf  # read by Adam.step: skip the update when 1

    def record(self, step: int, loss: torch.Tensor, params: dict[str, torch.Tensor]) -> None:
        """Record step ``step`` (loss scalar, gradients of ``params`` in ``names`` order)."""
        sums = [loss.detach().reshape(())]
        sums += [p.grad.sum() if p.grad is not None else torch.zeros((), device=loss.device)
                 for p in (params[k] for k in self.names)]
        bad = ~torch.isfinite(torch.stack(sums))
        any_bad = bad.any()
        self.found_inf.copy_(any_bad)
        first = any_bad & (self.first_bad == 0)
        self.first_bad = torch.where(first, step, self.first_bad)
        self.bad = torch.where(first, bad, self.bad)
        self.loss = torch.where(first, sums[0].float(), self.loss)
        if not self.deferred:
            self.check()

    def failure(self) -> tuple[int, str] | None:
        """(iteration, what) of the first non-finite step, or None (one host read)."""
        step = int(self.first_bad)
        if step == 0:
            return None
        bad = self.bad.tolist()
        if bad[0]:
            return step, f"loss is {float(self.loss)}"
        return step, f"non-finite gradient of {[n for n, b in zip(self.names, bad[1:]) if b]}"

    def check(self) -> None:
        """Raise (``on_failure``, else :class:`FitDivergedError`) if a recorded step was not finite."""
        f = self.failure()
        if f is None:
            return
        if self.on_failure is not None:
            self.on_failure(*f)
        raise FitDivergedError(f"static fit diverged at iteration {f[0]}: {f[1]}")


def raise_diverged(what: str, step: int, last_good: dict[str, Any], bar) -> None:
    """Raise :class:`FitDivergedError` at ``step`` naming ``last_good`` (closes the progress ``bar``)."""
    if bar is not None:
        bar.close()
    if last_good["path"] is not None:
        where = f"last good checkpoint (iteration {last_good['iteration']}) kept at {last_good['path']}"
    else:
        where = "no checkpoint was written (pass checkpoint_path to keep one)"
    raise FitDivergedError(f"static fit diverged at iteration {step}: {what}; {where}. "
                           "Lower the learning rates or check the input images for invalid values")
