"""anigs.animate.adam.Adam against torch.optim.Adam + ExponentialLR: the same bits on the CPU."""
import pytest
import torch

from anigs.animate.adam import Adam


def _train(make, steps=25, seed=0):
    g = torch.Generator().manual_seed(seed)
    a = torch.randn(40, 3, 12, generator=g).requires_grad_()
    b = torch.randn(7, 4, generator=g).requires_grad_()
    groups = [{"params": [a], "lr": 3e-3, "name": "a"}, {"params": [b], "lr": 1e-2, "name": "b"}]
    opt, after = make(groups)
    for it in range(steps):
        loss = (a.sin() * torch.randn(a.shape, generator=g)).sum() + (b ** 2).sum() * 1e-3
        if it % 5 == 3:  # a step where one parameter has no gradient
            loss = (b ** 3).sum()
        opt.zero_grad(set_to_none=True) if isinstance(opt, torch.optim.Optimizer) else opt.zero_grad()
        loss.backward()
        opt.step()
        after()
    return a.detach(), b.detach(), [grp["lr"] for grp in opt.param_groups]


@pytest.mark.parametrize("gamma", [1.0, 0.01 ** (1 / 25)])
def test_same_bits_as_torch_adam_with_exponential_decay(gamma):
    def torch_make(groups):
        opt = torch.optim.Adam(groups, eps=1e-15)
        sched = torch.optim.lr_scheduler.ExponentialLR(opt, gamma)
        return opt, sched.step

    def ours_make(groups):
        return Adam(groups, eps=1e-15, gamma=gamma), lambda: None

    ta, tb, tlr = _train(torch_make)
    oa, ob, olr = _train(ours_make)
    assert torch.equal(ta, oa) and torch.equal(tb, ob)
    assert tlr == olr


def test_bad_groups_fail_clearly():
    p = torch.zeros(3, requires_grad=True)
    with pytest.raises(ValueError, match="no parameter groups"):
        Adam([])
    with pytest.raises(ValueError, match="invalid learning rate"):
        Adam([{"params": [p], "lr": float("nan"), "name": "p"}])
