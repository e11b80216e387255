"""The Gaussian set: raw parameters, their activations, and standard 3DGS PLY IO.

Raw parameters (what optimisers see):
    means      [N,3]   world positions
    quats      [N,4]   rotations w,x,y,z, any norm (normalised on use)
    log_scales [N,3]   log of per-axis standard deviations
    opacity_logits [N] logit of opacity
    sh         [N,C,3] SH coefficients, C = (degree+1)^2; sh[:,0] is the DC term

PLY layout (as written by the original 3DGS code and read by every viewer):
``x y z nx ny nz f_dc_0..2 f_rest_0..(3C-4) opacity scale_0..2 rot_0..3``, float32,
``f_rest`` channel-major (all R coefficients, then G, then B).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

import numpy as np
import torch

from anigs.io import atomic_path

SH_C0 = 0.28209479177387814


def sh_degree_from_coeffs(num_coeffs: int) -> int:
    """SH degree for C = (deg+1)^2 coefficients."""
    deg = int(round(num_coeffs**0.5)) - 1
    if (deg + 1) ** 2 != num_coeffs or deg < 0 or deg > 3:
        raise ValueError(f"{num_coeffs} SH coefficients is not (deg+1)^2 for a degree in 0..3")
    return deg


def rgb_to_sh0(rgb: torch.Tensor) -> torch.Tensor:
    """DC SH coefficient giving colour ``rgb`` (in [0,1])."""
    return (rgb - 0.5) / SH_C0


def sh0_to_rgb(sh0: torch.Tensor) -> torch.Tensor:
    return sh0 * SH_C0 + 0.5


@dataclass
class Gaussians:
    """A set of N 3D Gaussians (raw parameters; see module docstring)."""

    means: torch.Tensor
    quats: torch.Tensor
    log_scales: torch.Tensor
    opacity_logits: torch.Tensor
    sh: torch.Tensor
    extras: dict = field(default_factory=dict)  # e.g. per-Gaussian labels [N] (not written to PLY)

    def __post_init__(self) -> None:
        n = self.means.shape[0]
        shapes = {
            "means": (self.means, (n, 3)),
            "quats": (self.quats, (n, 4)),
            "log_scales": (self.log_scales, (n, 3)),
            "opacity_logits": (self.opacity_logits, (n,)),
        }
        for name, (t, shape) in shapes.items():
            if tuple(t.shape) != shape:
                raise ValueError(f"Gaussians.{name}: expected shape {shape}, got {tuple(t.shape)}")
        if self.sh.ndim != 3 or self.sh.shape[0] != n or self.sh.shape[2] != 3:
            raise ValueError(f"Gaussians.sh: expected [N,C,3], got {tuple(self.sh.shape)}")
        sh_degree_from_coeffs(self.sh.shape[1])

    # ---- construction --------------------------------------------------------
    @staticmethod
    def from_points(
        points: torch.Tensor, colors: torch.Tensor, scales: torch.Tensor | float = 0.01,
        opacity: float = 0.1, sh_degree: int = 0,
    ) -> "Gaussians":
        """Isotropic Gaussians at ``points`` [N,3] with ``colors`` [N,3] in [0,1]."""
        n = points.shape[0]
        points = points.float()
        if not torch.is_tensor(scales):
            scales = torch.full((n,), float(scales))
        scales = scales.float().reshape(n, -1).expand(n, 3)
        sh = torch.zeros(n, (sh_degree + 1) ** 2, 3)
        sh[:, 0] = rgb_to_sh0(colors.float().clamp(0, 1))
        quats = torch.zeros(n, 4)
        quats[:, 0] = 1
        op = torch.full((n,), float(opacity)).clamp(1e-6, 1 - 1e-6)
        return Gaussians(points.clone(), quats, scales.clamp_min(1e-8).log().clone(), torch.logit(op), sh)

    @property
    def num(self) -> int:
        return self.means.shape[0]

    @property
    def sh_degree(self) -> int:
        return sh_degree_from_coeffs(self.sh.shape[1])

    @property
    def device(self) -> torch.device:
        return self.means.device

    # ---- activations ---------------------------------------------------------
    @property
    def scales(self) -> torch.Tensor:
        """Activated per-axis standard deviations [N,3]."""
        return torch.exp(self.log_scales)

    @property
    def opacities(self) -> torch.Tensor:
        """Activated opacities [N]."""
        return torch.sigmoid(self.opacity_logits)

    @property
    def rgb(self) -> torch.Tensor:
        """View-independent base colour from the DC term [N,3]."""
        return sh0_to_rgb(self.sh[:, 0])

    # ---- manipulation --------------------------------------------------------
    def params(self) -> dict[str, torch.Tensor]:
        return {
            "means": self.means, "quats": self.quats, "log_scales": self.log_scales,
            "opacity_logits": self.opacity_logits, "sh": self.sh,
        }

    def to(self, device: torch.device | str) -> "Gaussians":
        return Gaussians(**{k: v.to(device) for k, v in self.params().items()},
                         extras={k: (v.to(device) if torch.is_tensor(v) else v) for k, v in self.extras.items()})

    def detach(self) -> "Gaussians":
        return Gaussians(**{k: v.detach().clone() for k, v in self.params().items()}, extras=dict(self.extras))

    def subset(self, index: torch.Tensor) -> "Gaussians":
        extras = {k: (v[index] if torch.is_tensor(v) and v.shape[:1] == (self.num,) else v) for k, v in self.extras.items()}
        return Gaussians(**{k: v[index] for k, v in self.params().items()}, extras=extras)

    def with_sh_degree(self, degree: int) -> "Gaussians":
        """Copy with SH truncated or zero-padded to ``degree``."""
        c = (degree + 1) ** 2
        sh = self.sh[:, :c]
        if sh.shape[1] < c:
            sh = torch.cat([sh, sh.new_zeros(self.num, c - sh.shape[1], 3)], 1)
        return Gaussians(self.means, self.quats, self.log_scales, self.opacity_logits, sh.contiguous(), dict(self.extras))

    @staticmethod
    def concat(parts: Iterable["Gaussians"]) -> "Gaussians":
        parts = list(parts)
        deg = max(p.sh_degree for p in parts)
        parts = [p.with_sh_degree(deg) for p in parts]
        keys = parts[0].params().keys()
        out = {k: torch.cat([p.params()[k] for p in parts]) for k in keys}
        extras = {}
        for k in parts[0].extras:
            if all(k in p.extras and torch.is_tensor(p.extras[k]) for p in parts):
                extras[k] = torch.cat([p.extras[k] for p in parts])
        return Gaussians(**out, extras=extras)

    def check_finite(self, what: str = "Gaussians") -> None:
        """Raise ValueError naming the first non-finite parameter."""
        for k, v in self.params().items():
            if not torch.isfinite(v).all():
                bad = int((~torch.isfinite(v)).reshape(v.shape[0], -1).any(1).sum())
                raise ValueError(f"{what}: parameter {k!r} has non-finite values in {bad} Gaussians")

    # ---- PLY IO ----------------------------------------------------------------
    def save_ply(self, path: str | Path) -> None:
        save_ply(self, path)

    @staticmethod
    def load_ply(path: str | Path) -> "Gaussians":
        return load_ply(path)


# ---------------------------------------------------------------------------
# PLY
_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def ply_property_names(sh_degree: int) -> list[str]:
    """Property order of the standard 3DGS PLY for a given SH degree."""
    n_rest = 3 * ((sh_degree + 1) ** 2 - 1)
    return (["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
            + [f"f_rest_{i}" for i in range(n_rest)]
            + ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"])


def save_ply(g: Gaussians, path: str | Path) -> None:
    """Write the standard 3DGS binary little-endian PLY (atomically)."""
    g = g.detach().to("cpu")
    n, c = g.num, g.sh.shape[1]
    names = ply_property_names(g.sh_degree)
    cols = [
        g.means.numpy(), np.zeros((n, 3), np.float32), g.sh[:, 0].numpy(),
        # channel-major: [N, 3, C-1] flattened
        g.sh[:, 1:].transpose(1, 2).reshape(n, 3 * (c - 1)).numpy(),
        g.opacity_logits[:, None].numpy(), g.log_scales.numpy(), g.quats.numpy(),
    ]
    data = np.concatenate(cols, axis=1).astype("<f4")
    assert data.shape[1] == len(names)
    header = "ply\nformat binary_little_endian 1.0\nelement vertex {}\n{}end_header\n".format(
        n, "".join(f"property float {p}\n" for p in names))
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(header.encode("ascii"))
            fh.write(np.ascontiguousarray(data).tobytes())


def read_ply_header(fh) -> tuple[str, list[tuple[str, int, list[tuple[str, str]]]]]:
    """The PLY header of the open binary file ``fh``: its format and its elements (name, count,
    [(property, numpy type code or 'list')]); ``fh`` is left at the first data byte."""
    first = fh.readline().strip()
    if first != b"ply":
        raise ValueError("not a PLY file (missing 'ply' magic)")
    fmt, elements = None, []
    while True:
        line = fh.readline()
        if not line:
            raise ValueError("PLY header has no end_header")
        tok = line.decode("ascii", "replace").split()
        if not tok or tok[0] in ("comment", "obj_info"):
            continue
        if tok[0] == "format":
            fmt = tok[1]
        elif tok[0] == "element":
            elements.append((tok[1], int(tok[2]), []))
        elif tok[0] == "property":
            if not elements:
                raise ValueError("PLY property before any element")
            if tok[1] == "list":
                elements[-1][2].append((tok[-1], "list"))
            else:
                if tok[1] not in _PLY_TYPES:
                    raise ValueError(f"PLY property type {tok[1]!r} not supported")
                elements[-1][2].append((tok[2], _PLY_TYPES[tok[1]]))
        elif tok[0] == "end_header":
            break
    if fmt is None:
        raise ValueError("PLY header has no format line")
    return fmt, elements


def load_ply(path: str | Path) -> Gaussians:
    """Read a 3DGS PLY (binary little/big endian or ascii; SH degree from the property count)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"PLY not found: {path}")
    with open(path, "rb") as fh:
        fmt, elements = read_ply_header(fh)
        if not elements or elements[0][0] != "vertex":
            raise ValueError(f"{path}: first PLY element must be 'vertex'")
        _, n, props = elements[0]
        if any(t == "list" for _, t in props):
            raise ValueError(f"{path}: list properties in the vertex element are not supported")
        if fmt == "ascii":
            rows = [fh.readline().split() for _ in range(n)]
            arr = {name: np.array([float(r[i]) for r in rows], np.float64) for i, (name, _) in enumerate(props)}
        else:
            endian = "<" if fmt == "binary_little_endian" else ">"
            dtype = np.dtype([(name, endian + t) for name, t in props])
            raw = fh.read(dtype.itemsize * n)
            if len(raw) < dtype.itemsize * n:
                raise ValueError(f"{path}: truncated PLY ({len(raw)} of {dtype.itemsize * n} vertex bytes)")
            rec = np.frombuffer(raw, dtype=dtype, count=n)
            arr = {name: rec[name].astype(np.float64) for name, _ in props}
    required = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
                "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    missing = [k for k in required if k not in arr]
    if missing:
        raise ValueError(f"{path}: not a 3DGS PLY, missing properties {missing}")
    rest_names = sorted((k for k in arr if k.startswith("f_rest_")), key=lambda s: int(s.split("_")[-1]))
    n_rest = len(rest_names)
    if n_rest % 3:
        raise ValueError(f"{path}: {n_rest} f_rest properties is not a multiple of 3")
    c = n_rest // 3 + 1
    sh_degree_from_coeffs(c)  # validates
    f32 = lambda keys: torch.from_numpy(np.stack([arr[k] for k in keys], 1).astype(np.float32))
    sh = torch.zeros(n, c, 3)
    sh[:, 0] = f32(["f_dc_0", "f_dc_1", "f_dc_2"])
    if n_rest:
        sh[:, 1:] = f32(rest_names).reshape(n, 3, c - 1).transpose(1, 2)
    return Gaussians(
        means=f32(["x", "y", "z"]),
        quats=f32(["rot_0", "rot_1", "rot_2", "rot_3"]),
        log_scales=f32(["scale_0", "scale_1", "scale_2"]),
        opacity_logits=f32(["opacity"])[:, 0].contiguous(),
        sh=sh.contiguous(),
    )
