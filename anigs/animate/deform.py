"""DCT deformation field over a canonical 3DGS: ``G^t = D_phi(G^0, t)`` (paper, Preliminaries).

Each *dynamic* Gaussian i carries DCT coefficients for a position offset and a rotation
offset; every scalar component follows the paper's basis

    v(t) = sqrt(2 / (K+1)) * sum_{k=1..K} phi_k * cos(pi / (2T) * (2t + 1) * k),

evaluable at any (also fractional) frame index t in [0, T-1]. With k = 1..K and K <= T-1
the basis is the non-constant part of the DCT-II, so it has zero mean over the T integer
frames: the canonical position is the temporal mean, and the offset at t = 0 is generally
not zero (the canonical loss of the model update pins the t = 0 render to the static
scene). k = T is identically zero on integer frames and k > T aliases lower bases, so
K > T - 1 is refused here (the model update clamps it, with a logged warning).

Rotation offsets: an axis-angle (so(3)) vector ``omega(t)`` [D,3], each component a DCT
series, mapped through the exponential map to a unit quaternion
``dq = (cos(|w|/2), sin(|w|/2) w/|w|)`` and composed on the left of the canonical
quaternion, ``q_t = dq (x) q_0`` (Hamilton product: the offset rotates the Gaussian in world
space). Why this choice: the rotation vector is a minimal, unconstrained, linear-in-time
parameter (a DCT series of it is meaningful, unlike a DCT of raw quaternion components
that leaves the unit sphere), its zero is the identity, and small offsets are linear in
the coefficients. ``dq`` is unit length, so the product keeps the norm of ``q_0`` (the
rasterizer normalises on use); zero coefficients give ``dq = (1,0,0,0)`` and the product
reproduces ``q_0`` bit for bit. The map uses a Taylor branch near zero so a zero-length
rotation offset has finite gradients.

Static Gaussians carry no coefficients: only the D dynamic rows are computed and scattered
into copies of ``means``/``quats``; all other attributes are the same tensors. Static rows are
therefore bit-identical at every t.

Optional smooth amplitude limits (per Gaussian, so per effect): offsets are squashed as
``L * tanh(|x| / L) * x / |x|`` (a smooth saturation, never a hard clip), with ``L`` a
fraction of the Gaussian's distance to its anchor (default anchor: its ground point
``(x, y, 0)``, i.e. the height above the z = 0 ground) and/or an absolute cap; the same
for rotation angles.

Optional per-Gaussian capacity: ``active_bases`` [D] (K_d <= K) keeps Gaussian d on the first
K_d bases only; its coefficients beyond K_d are zero and stay zero (the offsets use the masked
coefficients, so their gradients are zero too). Absent (the default) = every Gaussian uses all K.
"""
from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import torch
from torch import nn

from anigs.animate.dct import dct_basis, max_num_bases, offset_limits, soft_limit
from anigs.gaussians import Gaussians
from anigs.geometry.quaternion import axis_angle_to_quat, quat_multiply
from anigs.io import atomic_path

__all__ = ["MODEL_FORMAT", "DCTDeformation", "dct_basis", "dynamic_index_from_mask", "load_model", "load_model_payload",
           "max_num_bases", "offset_limits", "resolve_num_bases", "save_model", "soft_limit"]

MODEL_FORMAT = "anigs-dct-v1"
# Numerical guard only (not an amplitude limit): offsets beyond this many world units or
# rotation vectors beyond this many radians are meaningless and would overflow float32 in
# the projection. Real training never gets near these values.
_OFFSET_GUARD = 1e6
_ANGLE_GUARD = 1e4


class DCTDeformation(nn.Module):
    """Per-Gaussian DCT coefficients for the D dynamic Gaussians of a canonical scene.

    Parameters: ``pos_coeffs`` [D,3,K] (world-space position offsets), ``rot_coeffs`` [D,3,K]
    (rotation vector in radians; absent when ``rotation=False``).
    Buffers: ``dynamic_index`` [D] long (rows of the canonical scene), ``max_offset`` [D]
    and ``max_angle`` [D] (smooth limits; absent = unlimited), ``active_bases`` [D] long (bases
    K_d <= K each Gaussian uses; absent = all K).
    """

    def __init__(self, dynamic_index: torch.Tensor, num_frames: int, num_bases: int,
                 rotation: bool = True, max_offset: torch.Tensor | None = None,
                 max_angle: torch.Tensor | None = None, num_gaussians: int | None = None,
                 active_bases: torch.Tensor | None = None) -> None:
        super().__init__()
        num_frames, num_bases = int(num_frames), int(num_bases)
        if num_frames < 1:
            raise ValueError(f"DCTDeformation: num_frames T must be >= 1, got {num_frames}")
        if num_bases < 0:
            raise ValueError(f"DCTDeformation: num_bases K must be >= 0, got {num_bases}")
        if num_bases > max_num_bases(num_frames):
            raise ValueError(
                f"DCTDeformation: K={num_bases} bases for T={num_frames} frames: K must be <= T-1 = "
                f"{max_num_bases(num_frames)} (basis k=T is zero on every frame and k>T aliases lower ones); "
                "use resolve_num_bases() to clamp")
        idx = torch.as_tensor(dynamic_index).long().reshape(-1)
        if idx.numel() and (int(idx.min()) < 0 or (num_gaussians is not None and int(idx.max()) >= num_gaussians)):
            raise ValueError(f"DCTDeformation: dynamic_index out of range [0, {num_gaussians})")
        if idx.numel() != torch.unique(idx).numel():
            raise ValueError("DCTDeformation: dynamic_index has duplicate entries")
        d = idx.numel()
        self.num_frames, self.num_bases, self.rotation = num_frames, num_bases, bool(rotation)
        self.num_gaussians = num_gaussians
        self.register_buffer("dynamic_index", idx)
        self.pos_coeffs = nn.Parameter(torch.zeros(d, 3, num_bases))
        self.rot_coeffs = nn.Parameter(torch.zeros(d, 3, num_bases)) if rotation else None
        for name, lim in (("max_offset", max_offset), ("max_angle", max_angle)):
            if lim is not None:
                lim = torch.as_tensor(lim, dtype=torch.float32).reshape(-1)
                if lim.numel() == 1 and d != 1:
                    lim = lim.expand(d).clone()
                if lim.shape != (d,) or not bool((lim > 0).all()):
                    raise ValueError(f"DCTDeformation: {name} must be [D]={d} positive values")
            self.register_buffer(name, lim)
        self.register_buffer("active_bases", None)
        self.set_active_bases(active_bases)

    def set_active_bases(self, active_bases: torch.Tensor | None) -> None:
        """Use only the first K_d bases for Gaussian d (``active_bases`` [D] ints in [0, K]; None:
        all K). Zeroes the coefficients beyond K_d, so they stay zero under training."""
        if active_bases is None:
            self.active_bases = None
            return
        ab = torch.as_tensor(active_bases).reshape(-1)
        if ab.is_floating_point() or ab.dtype == torch.bool:
            raise ValueError(f"DCTDeformation: active_bases must be integers, got {ab.dtype}")
        ab = ab.long().to(self.dynamic_index.device)
        if ab.shape != (self.num_dynamic,):
            raise ValueError(f"DCTDeformation: active_bases must be [D]={self.num_dynamic} values, got {tuple(ab.shape)}")
        if ab.numel() and (int(ab.min()) < 0 or int(ab.max()) > self.num_bases):
            raise ValueError(f"DCTDeformation: active_bases must be in [0, K={self.num_bases}], "
                             f"got [{int(ab.min())}, {int(ab.max())}]")
        self.active_bases = ab
        m = self.coeff_mask()
        with torch.no_grad():
            self.pos_coeffs.mul_(m)
            if self.rot_coeffs is not None:
                self.rot_coeffs.mul_(m)

    def coeff_mask(self) -> torch.Tensor | None:
        """[D,1,K] 1/0 mask of the bases each Gaussian uses (None: all K)."""
        if self.active_bases is None:
            return None
        k = torch.arange(self.num_bases, device=self.active_bases.device)
        return (k[None, :] < self.active_bases[:, None]).to(self.pos_coeffs.dtype)[:, None, :]

    # ---- evaluation -------------------------------------------------------------
    @property
    def num_dynamic(self) -> int:
        return int(self.dynamic_index.numel())

    def basis(self, t: torch.Tensor | float | int) -> torch.Tensor:
        """[K] (scalar t) or [B,K]; see :func:`dct_basis`."""
        tt = torch.as_tensor(t, dtype=torch.float64)
        if bool(((tt < 0) | (tt > self.num_frames - 1)).any()):
            raise ValueError(f"frame index t={t} outside [0, T-1] = [0, {self.num_frames - 1}]")
        return dct_basis(tt, self.num_frames, self.num_bases, self.pos_coeffs.dtype, self.pos_coeffs.device)

    def offsets(self, t: torch.Tensor | float | int) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Position offsets [D,3] and rotation-offset quaternions [D,4] (None without rotation) at t."""
        b = self.basis(t)
        m = self.coeff_mask()
        pos = self.pos_coeffs if m is None else self.pos_coeffs * m
        dmu = pos @ b  # [D,3]
        dmu = torch.nan_to_num(dmu, nan=0.0).clamp(-_OFFSET_GUARD, _OFFSET_GUARD)
        if self.max_offset is not None:
            dmu = soft_limit(dmu, self.max_offset)
        dq = None
        if self.rot_coeffs is not None:
            rot = self.rot_coeffs if m is None else self.rot_coeffs * m
            w = torch.nan_to_num(rot @ b, nan=0.0).clamp(-_ANGLE_GUARD, _ANGLE_GUARD)
            if self.max_angle is not None:
                w = soft_limit(w, self.max_angle)
            dq = axis_angle_to_quat(w)
        return dmu, dq

    def forward(self, canonical: Gaussians, t: torch.Tensor | float | int) -> Gaussians:
        """Deformed Gaussians at frame t; static rows are the canonical values, bit for bit."""
        if self.num_gaussians is not None and canonical.num != self.num_gaussians:
            raise ValueError(f"deformation was built for {self.num_gaussians} Gaussians, canonical has {canonical.num}")
        if self.num_dynamic == 0:
            return canonical
        idx = self.dynamic_index
        dmu, dq = self.offsets(t)
        means = canonical.means.index_copy(0, idx, canonical.means[idx] + dmu)
        quats = canonical.quats
        if dq is not None:
            quats = quats.index_copy(0, idx, quat_multiply(dq, quats[idx]))
        return Gaussians(means, quats, canonical.log_scales, canonical.opacity_logits, canonical.sh,
                         extras=canonical.extras)

    def trajectories(self, canonical_means: torch.Tensor, times: torch.Tensor) -> torch.Tensor:
        """Positions of the dynamic Gaussians over time [B,D,3] (canonical_means [N,3], times [B])."""
        mu = canonical_means[self.dynamic_index]
        return torch.stack([mu + self.offsets(t)[0] for t in times])

    # ---- maintenance ------------------------------------------------------------
    def remapped(self, new_index: torch.Tensor, max_offset: torch.Tensor | None = None,
                 max_angle: torch.Tensor | None = None) -> "DCTDeformation":
        """Copy for another dynamic set: coefficients (and ``active_bases``, when set) kept where the
        Gaussian stays dynamic; new ones start at zero (with all K bases)."""
        new = DCTDeformation(new_index, self.num_frames, self.num_bases, self.rotation,
                             max_offset, max_angle, self.num_gaussians)
        old_pos = {int(i): r for r, i in enumerate(self.dynamic_index.tolist())}
        src, dst = [], []
        for r, i in enumerate(new.dynamic_index.tolist()):
            if i in old_pos:
                src.append(old_pos[i])
                dst.append(r)
        if src:
            s, d = torch.tensor(src), torch.tensor(dst)
            with torch.no_grad():
                new.pos_coeffs[d] = self.pos_coeffs.detach()[s]
                if new.rot_coeffs is not None and self.rot_coeffs is not None:
                    new.rot_coeffs[d] = self.rot_coeffs.detach()[s]
        if self.active_bases is not None:
            ab = torch.full((new.num_dynamic,), self.num_bases, dtype=torch.long)
            if src:
                ab[d] = self.active_bases.cpu()[s]
            new.set_active_bases(ab)
        return new

    def state(self) -> dict[str, Any]:
        """Plain dict of the field (tensors detached to CPU; ``active_bases`` only when set, so a
        field without it writes the same checkpoint bytes as before the key existed)."""
        cpu = lambda x: None if x is None else x.detach().cpu().clone()
        s = {
            "num_frames": self.num_frames, "num_bases": self.num_bases, "rotation": self.rotation,
            "num_gaussians": self.num_gaussians, "dynamic_index": cpu(self.dynamic_index),
            "pos_coeffs": cpu(self.pos_coeffs), "rot_coeffs": cpu(self.rot_coeffs),
            "max_offset": cpu(self.max_offset), "max_angle": cpu(self.max_angle),
        }
        if self.active_bases is not None:  # int16: K <= T-1 is far below 2^15
            s["active_bases"] = cpu(self.active_bases).to(torch.int16 if self.num_bases < 2**15 else torch.long)
        return s

    @staticmethod
    def from_state(s: dict[str, Any]) -> "DCTDeformation":
        d = DCTDeformation(s["dynamic_index"], s["num_frames"], s["num_bases"], s["rotation"],
                           s.get("max_offset"), s.get("max_angle"), s.get("num_gaussians"), s.get("active_bases"))
        with torch.no_grad():
            if tuple(s["pos_coeffs"].shape) != tuple(d.pos_coeffs.shape):
                raise ValueError(f"pos_coeffs shape {tuple(s['pos_coeffs'].shape)} != {tuple(d.pos_coeffs.shape)}")
            d.pos_coeffs.copy_(s["pos_coeffs"])
            if d.rot_coeffs is not None:
                if s.get("rot_coeffs") is None or tuple(s["rot_coeffs"].shape) != tuple(d.rot_coeffs.shape):
                    raise ValueError("rot_coeffs missing or of the wrong shape")
                d.rot_coeffs.copy_(s["rot_coeffs"])
            if d.active_bases is not None:  # a stored field has zeros there already; keep it exact
                d.set_active_bases(d.active_bases)
        return d


def resolve_num_bases(num_bases: int, num_frames: int, log=None) -> int:
    """Clamp K to T-1 (logging a warning through ``log`` when it changes)."""
    k = min(int(num_bases), max_num_bases(num_frames))
    if k != num_bases and log is not None:
        log.warning("num_bases K=%d is more than T-1=%d for T=%d frames: clamped to K=%d",
                    num_bases, max_num_bases(num_frames), num_frames, k)
    return k


def dynamic_index_from_mask(mask: torch.Tensor, num_gaussians: int | None = None) -> torch.Tensor:
    """Dynamic rows [D] long from a per-Gaussian mask [N] (bool, or integer labels with 0 = static)."""
    mask = torch.as_tensor(mask)
    if mask.ndim != 1:
        raise ValueError(f"dynamic mask must be 1-D [N], got shape {tuple(mask.shape)}")
    if num_gaussians is not None and mask.shape[0] != num_gaussians:
        raise ValueError(f"dynamic mask has {mask.shape[0]} entries but the canonical scene has {num_gaussians} Gaussians")
    return torch.nonzero(mask != 0, as_tuple=False).reshape(-1)


# ---- model.pt -------------------------------------------------------------------
def _check_finite_tree(obj: Any, where: str, path: str) -> None:
    if torch.is_tensor(obj):
        if obj.is_floating_point() and not bool(torch.isfinite(obj).all()):
            bad = int((~torch.isfinite(obj)).sum())
            raise ValueError(f"{where}: tensor {path!r} has {bad} non-finite values (NaN/Inf): refusing this checkpoint")
    elif isinstance(obj, dict):
        for k, v in obj.items():
            _check_finite_tree(v, where, f"{path}.{k}" if path else str(k))
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            _check_finite_tree(v, where, f"{path}[{i}]")


def save_model(path: str | Path, deformation: DCTDeformation, canonical: Gaussians,
               config: dict | None = None, store_all_attributes: bool = False,
               extra: dict | None = None) -> None:
    """Write ``model.pt`` atomically.

    Holds the field (coefficients, dynamic index, K, T, limits), the canonical positions
    [N,3] (trained in the paper's default), all canonical attributes when
    ``store_all_attributes`` (the "all" parameter group), and the config. Refuses to write
    non-finite tensors.
    """
    payload: dict[str, Any] = {
        "format": MODEL_FORMAT,
        "deformation": deformation.state(),
        "canonical_means": canonical.means.detach().cpu().clone(),
        "canonical": ({k: v.detach().cpu().clone() for k, v in canonical.params().items()}
                      if store_all_attributes else None),
        "config": dict(config or {}),
        "extra": dict(extra or {}),
    }
    _check_finite_tree(payload, f"save_model({path})", "")
    # save through a buffer: torch.save names the zip archive after the file, and the atomic
    # temporary name is random, which would make identical models differ byte for byte
    buf = io.BytesIO()
    torch.save(payload, buf)
    with atomic_path(path) as tmp:
        tmp.write_bytes(buf.getvalue())


def load_model_payload(path: str | Path) -> dict[str, Any]:
    """Read and validate ``model.pt`` (format, finiteness of every tensor)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"model checkpoint not found: {path}")
    payload = torch.load(path, map_location="cpu", weights_only=True)
    if not isinstance(payload, dict) or payload.get("format") != MODEL_FORMAT:
        raise ValueError(f"{path}: not an anigs model checkpoint (format {MODEL_FORMAT!r} expected)")
    _check_finite_tree(payload, str(path), "")
    return payload


def load_model(path: str | Path, canonical: Gaussians | str | Path | None = None
               ) -> tuple[Gaussians | None, DCTDeformation, dict[str, Any]]:
    """Load ``model.pt``; with the canonical scene (Gaussians or PLY path) also rebuild the
    trained canonical Gaussians.

    Returns (canonical Gaussians with the checkpoint's positions/attributes applied, or None
    when ``canonical`` is None; the deformation; the raw payload).
    """
    payload = load_model_payload(path)
    deformation = DCTDeformation.from_state(payload["deformation"])
    if canonical is None:
        return None, deformation, payload
    if not isinstance(canonical, Gaussians):
        canonical = Gaussians.load_ply(canonical)
    means = payload["canonical_means"]
    if means.shape != canonical.means.shape:
        raise ValueError(f"{path}: checkpoint has canonical positions for {means.shape[0]} Gaussians, "
                         f"the canonical scene has {canonical.num}")
    if deformation.num_gaussians is not None and deformation.num_gaussians != canonical.num:
        raise ValueError(f"{path}: deformation built for {deformation.num_gaussians} Gaussians, canonical has {canonical.num}")
    params = canonical.params()
    if payload.get("canonical") is not None:
        for k, v in payload["canonical"].items():
            if k not in params or params[k].shape[0] != v.shape[0]:
                raise ValueError(f"{path}: stored canonical attribute {k!r} does not match the canonical scene")
            params[k] = v.to(params[k].dtype)
    params["means"] = means.to(canonical.means.dtype)
    return Gaussians(**params, extras=dict(canonical.extras)), deformation, payload
