"""Differentiable Gaussian splatting: ``rasterize`` (flat tensors) and ``render_gaussians``."""
from anigs.render.rasterize import BACKENDS, rasterize, render_gaussians, select_backend

__all__ = ["BACKENDS", "rasterize", "render_gaussians", "select_backend"]
