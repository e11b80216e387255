"""The ``fvd_gt`` config section (:class:`FvdGtConfig`): FVD against the synthetic ground-truth motion on
evaluation-only views (:mod:`anigs.metrics.fvd_gt`; the stage: :mod:`anigs.stages.fvd_gt`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from anigs.typed_config import Section
from anigs.metrics.eval_views import Placement

WHEN = ("tables", "always", "never")

@dataclass
class FvdGtConfig(Section):
    """``fvd_gt`` config section."""

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
    background: list = field(default_factory=lambda: [0.62, 0.76, 0.92])  # background colour (RGB in [0,1])
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
