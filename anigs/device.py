"""Device selection and seeding. Never hard-codes ``cuda``: ``auto`` picks it when present."""
from __future__ import annotations

import os
import random

import numpy as np
import torch


def get_device(pref: str = "auto") -> torch.device:
    """Resolve ``auto`` | ``cpu`` | ``cuda`` | ``cuda:N`` to a device; a GPU request without one is an error."""
    if pref in (None, "", "auto"):
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    dev = torch.device(pref)
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise RuntimeError(f"device {pref!r} requested but no CUDA device is available on this machine; "
                           "set device: auto (or cpu) in the config")
    return dev


def seed_everything(seed: int) -> torch.Generator:
    """Seed python, numpy and torch; return a CPU torch.Generator seeded with ``seed``."""
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)
    os.environ.setdefault("PYTHONHASHSEED", str(seed))
    return torch.Generator().manual_seed(seed)


def check_workflow_device(device: str) -> None:
    """The workflow's global ``device``: a cuda setting on a machine without a CUDA device fails when the
    workflow is parsed, before any job starts, naming what to use instead."""
    if str(device).startswith("cuda") and not torch.cuda.is_available():
        raise ValueError(f"config: device is {device!r} but this machine has no CUDA device; use device: auto "
                         "(or cpu), or submit to a GPU cluster with --profile workflow/profiles/slurm")
