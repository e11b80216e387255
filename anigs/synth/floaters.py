"""Synthetic captures with sky and floaters: what a sparse capture's fit puts where no photo
resolves anything.

- :func:`sky_needles`: long, blurry, needle-like Gaussians high above the scene, seen from
  every photo (the splats that cross the empty sky of a facade walk-around fitted from 11 photos).
- :func:`sky_blobs`: huge smooth isotropic Gaussians around the scene (the blur around a close-up).
- :func:`with_floaters`: a scene with both added, and the flags of what was added.
- :func:`sparse_capture_config`: the synthetic capture of 11 photos walking along the facade
  (``synthetic.capture.layout: facade``), sky above it.
"""
from __future__ import annotations

import math

import numpy as np
import torch

from anigs.gaussians import Gaussians
from anigs.synth.capture import CameraPathConfig, SynthConfig
from anigs.synth.scene import SceneConfig


def _quat_from_axis(axis: np.ndarray) -> np.ndarray:
    """Unit quaternions w,x,y,z [M,4] rotating +x onto the unit vectors ``axis`` [M,3]."""
    x = np.array([1.0, 0.0, 0.0])
    out = np.zeros((len(axis), 4))
    for i, a in enumerate(axis):
        a = a / np.linalg.norm(a)
        c = float(np.clip(x @ a, -1, 1))
        v = np.cross(x, a)
        if np.linalg.norm(v) < 1e-9:
            out[i] = [1, 0, 0, 0] if c > 0 else [0, 0, 0, 1]
            continue
        half = math.acos(c) / 2
        out[i, 0] = math.cos(half)
        out[i, 1:] = math.sin(half) * v / np.linalg.norm(v)
    return out


def sky_needles(n: int, center: np.ndarray, radius: float, height: float, length: float,
                rng: np.random.Generator, colour=(0.85, 0.55, 0.3)) -> Gaussians:
    """``n`` needles: centres in a disc of ``radius`` at ``height`` above ``center`` [3] (+z up),
    largest std dev ``length``, the other two ``length / 60``, random horizontal-ish axes,
    opacity 0.6, colour ``colour`` (SH degree 0)."""
    r = radius * np.sqrt(rng.uniform(0, 1, n))
    a = rng.uniform(0, 2 * np.pi, n)
    pos = np.asarray(center, float) + np.stack([r * np.cos(a), r * np.sin(a), np.full(n, height)], 1)
    az, el = rng.uniform(0, 2 * np.pi, n), rng.uniform(-0.3, 0.3, n)
    axis = np.stack([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)], 1)
    g = Gaussians.from_points(torch.from_numpy(pos).float(), torch.tensor([colour] * n, dtype=torch.float32),
                              torch.full((n,), float(length)), opacity=0.6)
    g.log_scales[:, 1:] -= math.log(60.0)
    g.quats = torch.from_numpy(_quat_from_axis(axis)).float()
    return g


def sky_blobs(n: int, center: np.ndarray, radius: float, height: float, size: float,
              rng: np.random.Generator, colour=(0.7, 0.75, 0.8)) -> Gaussians:
    """``n`` huge isotropic blobs of std dev ``size`` on a ring of ``radius`` at ``height``."""
    a = rng.uniform(0, 2 * np.pi, n)
    pos = np.asarray(center, float) + np.stack([radius * np.cos(a), radius * np.sin(a), np.full(n, height)], 1)
    return Gaussians.from_points(torch.from_numpy(pos).float(), torch.tensor([colour] * n, dtype=torch.float32),
                                 torch.full((n,), float(size)), opacity=0.7)


def with_floaters(g: Gaussians, seed: int = 0, needles: int = 60, blobs: int = 12,
                  height: float = 6.0) -> tuple[Gaussians, np.ndarray]:
    """``g`` plus sky needles and blobs above its centre (+z up, scaled to its horizontal size);
    returns (Gaussians, bool [N] True on the added floaters)."""
    rng = np.random.default_rng(seed)
    means = g.means.detach().double().numpy()
    lo, hi = np.percentile(means, 2, 0), np.percentile(means, 98, 0)
    center = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, hi[2]])
    size = float(max(hi[0] - lo[0], hi[1] - lo[1]))
    parts = [g.with_sh_degree(0) if g.sh_degree else g]
    if needles:
        parts.append(sky_needles(needles, center, 0.6 * size, height, 0.25 * size, rng))
    if blobs:
        parts.append(sky_blobs(blobs, center, 0.8 * size, 0.6 * height, 0.12 * size, rng))
    out = Gaussians.concat(parts)
    flags = np.zeros(out.num, bool)
    flags[g.num:] = True
    return out, flags


def sparse_capture_config(seed: int = 0, num_images: int = 11, num_gaussians: int = 12000,
                          width: int = 160, height: int = 120):
    """:class:`anigs.synth.SynthConfig` of a sparse facade walk: ``num_images`` photos along the
    facade of the bare courtyard (walls and paving, sky above)."""

    return SynthConfig(seed=seed, scene=SceneConfig(num_gaussians=num_gaussians, layout="courtyard"),
                       capture=CameraPathConfig(num_images=num_images, width=width, height=height, layout="facade",
                                             pos_jitter=0.03, rot_jitter_deg=1.0))
