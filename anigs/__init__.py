"""AniGS: animate static 3D Gaussian Splatting scenes with video priors."""
import os as _os

# OpenMP threads (torch's and the rasterizer's) must sleep when idle, not spin: parallel
# Snakemake jobs oversubscribe small machines, and spinning made a render 12x slower there.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

__version__ = "0.13.0"
