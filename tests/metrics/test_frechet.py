"""Fréchet distance: closed form for Gaussians, an independent oracle, and the guards."""
from __future__ import annotations

import numpy as np
import pytest

from anigs.metrics import frechet as fr
from anigs.metrics.frechet import feature_stats, frechet_distance, frechet_distance_from_stats


def oracle_fd(x: np.ndarray, y: np.ndarray) -> float:
    """Independent implementation of the pytorch-fid / torchmetrics formula.

    FD = |mu1-mu2|^2 + tr(S1) + tr(S2) - 2 tr sqrt(S1 S2), where tr sqrt(S1 S2) is the sum of
    the square roots of the eigenvalues of S1 S2 (real, non-negative for PSD S1, S2), as
    torchmetrics computes it from ``eigvals(sigma1 @ sigma2)``.
    """
    mu1, mu2 = x.mean(0), y.mean(0)
    s1 = np.cov(x, rowvar=False)
    s2 = np.cov(y, rowvar=False)
    ev = np.linalg.eigvals(s1 @ s2)
    tr_sqrt = np.sqrt(np.clip(ev.real, 0, None)).sum()
    return float(((mu1 - mu2) ** 2).sum() + np.trace(s1) + np.trace(s2) - 2 * tr_sqrt)


def test_closed_form_diagonal_gaussians():
    # N(m1, diag(a)) vs N(m2, diag(b)): FD = |m1-m2|^2 + sum (sqrt(a) - sqrt(b))^2
    rng = np.random.default_rng(0)
    d = 7
    m1, m2 = rng.normal(size=d), rng.normal(size=d)
    a, b = rng.uniform(0.1, 3, d), rng.uniform(0.1, 3, d)
    expected = ((m1 - m2) ** 2).sum() + ((np.sqrt(a) - np.sqrt(b)) ** 2).sum()
    res = frechet_distance_from_stats(m1, np.diag(a), m2, np.diag(b), n1=100, n2=100)
    assert res.value == pytest.approx(expected, rel=1e-10)
    assert res.dim == d and res.eps_used == 0.0 and not res.undersampled


def test_closed_form_rotated_isotropic():
    # isotropic covariances commute with any rotation: FD = |dm|^2 + d (s1 - s2)^2
    rng = np.random.default_rng(1)
    d = 5
    q, _ = np.linalg.qr(rng.normal(size=(d, d)))
    s1, s2 = 0.7, 1.9
    m1, m2 = q @ np.ones(d), q @ np.zeros(d)
    res = frechet_distance_from_stats(m1, s1**2 * np.eye(d), m2, s2**2 * np.eye(d))
    assert res.value == pytest.approx(d + d * (s1 - s2) ** 2, rel=1e-10)


def test_identical_sets_are_zero_and_samples_converge_to_closed_form():
    rng = np.random.default_rng(2)
    x = rng.normal(size=(500, 4))
    assert frechet_distance(x, x).value == pytest.approx(0.0, abs=1e-8)
    # large samples of two known Gaussians approach the closed form
    d = 4
    a, b = np.array([1.0, 2.0, 0.5, 1.5]), np.array([2.0, 1.0, 1.0, 0.3])
    x = rng.normal(size=(200_000, d)) * np.sqrt(a) + 1.0
    y = rng.normal(size=(200_000, d)) * np.sqrt(b)
    expected = d * 1.0 + ((np.sqrt(a) - np.sqrt(b)) ** 2).sum()
    assert frechet_distance(x, y).value == pytest.approx(expected, rel=0.02)


@pytest.mark.parametrize("n1,n2,d", [(300, 250, 16), (50, 80, 8), (40, 30, 64)])
def test_matches_independent_oracle(n1, n2, d):
    rng = np.random.default_rng(n1 + d)
    mix = rng.normal(size=(d, d)) / np.sqrt(d)
    x = rng.normal(size=(n1, d)) @ mix
    y = rng.normal(size=(n2, d)) @ (mix + 0.3 * rng.normal(size=(d, d)) / np.sqrt(d)) + 0.2
    res = frechet_distance(x, y)
    ref = oracle_fd(x, y)
    assert res.value == pytest.approx(ref, rel=1e-6, abs=1e-6)
    assert (res.n1, res.n2, res.dim) == (n1, n2, d)
    assert res.undersampled == (min(n1, n2) < d)


def test_undersampled_flag_and_warning():
    rng = np.random.default_rng(3)
    x, y = rng.normal(size=(10, 32)), rng.normal(size=(12, 32))
    res = frechet_distance(x, y)
    assert res.undersampled and any("fewer samples" in w for w in res.warnings)
    assert np.isfinite(res.value) and res.value > 0
    assert res.to_dict()["n1"] == 10


@pytest.mark.parametrize("n", [0, 1])
def test_fewer_than_two_samples_is_an_error(n):
    x = np.zeros((n, 3))
    with pytest.raises(ValueError, match="at least 2 samples"):
        frechet_distance(x, np.random.default_rng(0).normal(size=(5, 3)))


def test_bad_inputs():
    rng = np.random.default_rng(4)
    with pytest.raises(ValueError, match="dimensions differ"):
        frechet_distance(rng.normal(size=(5, 3)), rng.normal(size=(5, 4)))
    bad = rng.normal(size=(5, 3))
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        feature_stats(bad)
    with pytest.raises(ValueError, match="2-D"):
        feature_stats(np.zeros(5))


def test_complex_sqrtm_triggers_diagonal_offset_retry(monkeypatch):
    """A materially complex sqrtm result is rejected; the retry with eps*I is used and reported."""
    calls = []
    real_sqrtm = fr.scipy.linalg.sqrtm

    def fake_sqrtm(m):
        calls.append(m.copy())
        if len(calls) == 1:
            return real_sqrtm(m) + 1j * np.eye(m.shape[0])  # large imaginary part
        return real_sqrtm(m)

    monkeypatch.setattr(fr.scipy.linalg, "sqrtm", fake_sqrtm)
    d = 3
    res = frechet_distance_from_stats(np.zeros(d), np.eye(d), np.ones(d), 4 * np.eye(d))
    assert len(calls) == 2 and res.eps_used == pytest.approx(1e-6)
    # offset covariances (1+e) I and (4+e) I: FD = |dm|^2 + d (sqrt(4+e) - sqrt(1+e))^2 ~ d + d
    assert res.value == pytest.approx(d + d * 1.0, rel=1e-5)
    assert any("diagonal" in w or "retried" in w for w in res.warnings)


def test_failing_sqrtm_raises_after_max_offset(monkeypatch):
    def broken(m):
        raise np.linalg.LinAlgError("boom")

    monkeypatch.setattr(fr.scipy.linalg, "sqrtm", broken)
    with pytest.raises(RuntimeError, match="diagonal offset"):
        frechet_distance_from_stats(np.zeros(2), np.eye(2), np.zeros(2), np.eye(2))


def test_negligible_imaginary_part_is_dropped(monkeypatch):
    real_sqrtm = fr.scipy.linalg.sqrtm
    monkeypatch.setattr(fr.scipy.linalg, "sqrtm", lambda m: real_sqrtm(m) + 1e-12j)
    res = frechet_distance_from_stats(np.zeros(2), np.eye(2), np.zeros(2), np.eye(2))
    assert res.eps_used == 0.0 and res.value == pytest.approx(0.0, abs=1e-9)


def test_singular_covariances_give_finite_value():
    # rank-1 covariances (all samples on a line): sqrtm of a singular product
    rng = np.random.default_rng(5)
    t = rng.normal(size=(50, 1))
    x = t @ np.array([[1.0, 2.0, 0.0]])
    y = t @ np.array([[0.0, 1.0, 1.0]]) + 0.5
    res = frechet_distance(x, y)
    assert np.isfinite(res.value)
    assert res.value == pytest.approx(oracle_fd(x, y), rel=1e-4, abs=1e-4)
