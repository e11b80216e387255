"""Parameters of the ``sfm`` stage (:class:`SfmConfig`, config section ``sfm``) and their checks."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

from anigs.configs import from_dict

MATCHERS = ("exhaustive", "sequential", "spatial")
MAPPERS = ("incremental", "global")
UNDISTORTED_MODELS = ("PINHOLE", "SIMPLE_PINHOLE")


@dataclass
class SfmConfig:
    """Parameters of the ``sfm`` stage (config section ``sfm``)."""

    camera_model: str = "SIMPLE_RADIAL"  # COLMAP camera model; SIMPLE_PINHOLE/PINHOLE for synthetic renders
    single_camera: bool = True  # all images share one camera (one device, fixed zoom)
    camera_params: Optional[list[float]] = None  # known intrinsics in COLMAP's order for camera_model
    matcher: str = "exhaustive"  # exhaustive | sequential | spatial (needs GPS/pose priors)
    sequential_overlap: int = 10  # neighbours matched per image by the sequential matcher
    spatial_max_neighbors: int = 50  # neighbours matched per image by the spatial matcher
    max_num_features: int = 8192  # SIFT features per image
    max_image_size: int = -1  # SIFT extraction downscales larger images (-1: never)
    sift_peak_threshold: float = 0.02 / 3  # SIFT detection threshold (COLMAP's default); lower finds more features in low-contrast or small images
    mapper: str = "incremental"  # incremental | global
    init_min_tri_angle: float = 16.0  # incremental mapper's initial-pair triangulation angle (deg)
    retry_init_min_tri_angle: Optional[float] = 4.0  # lower angle for the retry; None disables the retry
    min_registered_fraction: float = 0.8  # fewer registered images than this fraction is an error
    refine: bool = True  # after mapping, bundle-adjust the cameras on the finest-scale keypoints (anigs.sfm.bundle)
    refine_max_keypoint_scale: float = 1.3  # refinement keeps keypoints up to this scale (sigma, px of the image SIFT ran on)
    refine_min_observations: int = 60  # refinement keeps at least this many (finest) observations per image
    refine_loss_scale: float = 0.5  # refinement's Cauchy loss scale, times the median reprojection error (0: plain least squares)
    undistort: bool = True  # undistort to PINHOLE when the camera model has distortion
    skip_unreadable: bool = False  # skip corrupt image files with a warning instead of failing
    ground_percentile: float = 5.0  # (no ground truth) this percentile of point heights is put at z=0
    camera_height: Optional[float] = 1.6  # (no ground truth) scale so the mean camera height is this; None keeps COLMAP's scale
    device: str = "auto"  # auto | cpu | cuda (SIFT extraction and matching)
    num_threads: int = 1  # COLMAP threads; 1 is bit-deterministic for a seed, -1 (all cores) is faster but not
    seed: int = 0  # COLMAP random seed

    @staticmethod
    def from_dict(d: dict[str, Any] | None) -> "SfmConfig":
        cfg = from_dict(SfmConfig, d, "sfm config", KeyError)
        cfg.validate()
        return cfg

    def validate(self) -> None:
        import pycolmap

        if self.camera_model not in pycolmap.CameraModelId.__members__:
            raise ValueError(f"sfm.camera_model {self.camera_model!r} is not a COLMAP camera model; "
                             f"choose one of {sorted(pycolmap.CameraModelId.__members__)}")
        if self.matcher not in MATCHERS:
            raise ValueError(f"sfm.matcher {self.matcher!r} not in {MATCHERS}")
        if self.mapper not in MAPPERS:
            raise ValueError(f"sfm.mapper {self.mapper!r} not in {MAPPERS}")
        if self.device not in ("auto", "cpu", "cuda"):
            raise ValueError(f"sfm.device {self.device!r} not in ('auto', 'cpu', 'cuda')")
        if not 0 < self.min_registered_fraction <= 1:
            raise ValueError(f"sfm.min_registered_fraction must be in (0, 1], got {self.min_registered_fraction}")
        if self.camera_height is not None and not self.camera_height > 0:
            raise ValueError(f"sfm.camera_height must be > 0 or null, got {self.camera_height}")
        if not 0 <= self.ground_percentile <= 100:
            raise ValueError(f"sfm.ground_percentile must be in [0, 100], got {self.ground_percentile}")
        if self.num_threads == 0 or self.num_threads < -1:
            raise ValueError(f"sfm.num_threads must be -1 (all cores) or >= 1, got {self.num_threads}")
        if not self.sift_peak_threshold > 0:
            raise ValueError(f"sfm.sift_peak_threshold must be > 0, got {self.sift_peak_threshold}")
        if not self.refine_max_keypoint_scale > 0:
            raise ValueError(f"sfm.refine_max_keypoint_scale must be > 0, got {self.refine_max_keypoint_scale}")
        if self.refine_min_observations < 0:
            raise ValueError(f"sfm.refine_min_observations must be >= 0, got {self.refine_min_observations}")
        if not self.refine_loss_scale >= 0:
            raise ValueError(f"sfm.refine_loss_scale must be >= 0, got {self.refine_loss_scale}")
        if self.camera_params is not None:
            probe = pycolmap.Camera.create_from_model_name(0, self.camera_model, 1.0, 2, 2)
            if len(self.camera_params) != len(probe.params):
                raise ValueError(f"sfm.camera_params has {len(self.camera_params)} values; camera model "
                                 f"{self.camera_model} takes {len(probe.params)} ({probe.params_info})")
        for key in ("init_min_tri_angle", "retry_init_min_tri_angle"):
            v = getattr(self, key)
            if v is not None and not 0 < v < 90:
                raise ValueError(f"sfm.{key} must be in (0, 90) degrees, got {v}")
