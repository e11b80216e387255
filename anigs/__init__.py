"""AniGS: animate static 3D Gaussian Splatting scenes with video priors."""
__version__ = "0.1.0"
