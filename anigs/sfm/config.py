"""Parameters of the ``sfm`` stage (:class:`SfmConfig`, config section ``sfm``) and their checks."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Optional, Union

from anigs.typed_config import Section

MATCHERS = ("auto", "exhaustive", "sequential", "spatial")
MAPPERS = ("incremental", "global")
UNDISTORTED_MODELS = ("PINHOLE", "SIMPLE_PINHOLE")
# camera models whose (mild) distortion the incremental mapper holds at zero with mapper_refine_distortion: auto
MILD_DISTORTION_MODELS = ("SIMPLE_RADIAL", "RADIAL")


@dataclass
class SfmConfig(Section):
    """Parameters of the ``sfm`` stage (config section ``sfm``)."""

    HANDED = ('seed', 'device')  # set once for the whole run (anigs.config.HANDED), not in this section

    camera_model: str = "SIMPLE_RADIAL"  # COLMAP camera model; SIMPLE_PINHOLE/PINHOLE for synthetic renders
    single_camera: bool = True  # all images share one camera (one device, fixed zoom)
    camera_params: Optional[list[float]] = None  # known intrinsics in COLMAP's order for camera_model
    #: auto | exhaustive | sequential | spatial (needs GPS/pose priors); auto: sequential when the photos are ordered
    #: like a video and exhaustive matching would be expensive, or more than exhaustive_max_images; else exhaustive
    #: (report.json says which and why)
    matcher: str = "auto"
    #: matcher auto: more photos than this are matched sequentially (exhaustive matching grows with the square of the
    #: count)
    exhaustive_max_images: int = 300
    #: matcher auto: ordered photos are matched sequentially when exhaustive matching would compare more descriptors
    #: than this (images^2/2 x keypoints^2; matching takes about 10 CPU s per 1e9, benchmarks/README.md)
    exhaustive_max_comparisons: float = 2.0e9
    #: the sequential matcher pairs image i with i+1, i+2, i+4, ..., i+2^(overlap-1) (COLMAP's quadratic overlap,
    #: images sorted by name)
    sequential_overlap: int = 10
    #: the sequential matcher also pairs each image with its this many most similar images (grey thumbnails): closes
    #: the loop of an orbit, joins the rows of a sweep; 0: COLMAP's pairs only
    sequential_similar: int = 3
    spatial_max_neighbors: int = 50  # neighbours matched per image by the spatial matcher
    #: SIFT features per image; COLMAP meets a smaller budget by dropping whole octaves, finest first (what the
    #: refinement uses)
    max_num_features: int = 8192
    max_image_size: int = -1  # SIFT extraction downscales larger images (-1: never)
    #: SIFT detection threshold (COLMAP's default); lower finds more features in low-contrast or small images
    sift_peak_threshold: float = 0.02 / 3
    mapper: str = "incremental"  # incremental | global
    #: incremental mapper's initial-pair triangulation angle (deg); auto: the largest of 16, 8, 4, 2, 1 that a matched
    #: pair reaches (COLMAP would otherwise search all pairs again at each halving)
    init_min_tri_angle: Union[float, str] = "auto"
    #: angle of the retry when the first mapping registers too few (runs only when below the first angle); None
    #: disables the retry
    retry_init_min_tri_angle: Optional[float] = 4.0
    #: a model with fewer registered images than this fraction escalates (anigs.sfm.escalate), then continues partial
    #: or fails
    min_registered_fraction: float = 0.8
    #: too few registered: add loop and look-alike pairs, then match every pair, then try the original photos of a
    #: downscaled capture, then the lower angle (false: only the lower angle)
    escalate: bool = True
    #: still below min_registered_fraction after the ladder: map the best matches again with up to this many other
    #: mapper seeds (seed + 1, seed + 2, ...: deterministic for a run's seed), each followed (every pair's matches)
    #: by every pair verified again with that seed and mapped; keep the model registering the most photos
    #: (anigs.sfm.escalate, rungs restart and reverify); 0: off
    mapper_restarts: int = 4
    #: below min_registered_fraction after escalating, continue with the largest model when it holds at least this
    #: fraction (the run is marked partial and the photos left out listed); below it, an error naming the likely cause
    partial_min_fraction: float = 0.5
    refine: bool = True  # after mapping, bundle-adjust the cameras on the finest-scale keypoints (anigs.sfm.bundle)
    #: refinement keeps keypoints up to this scale (sigma, px of the image SIFT ran on)
    refine_max_keypoint_scale: float = 1.3
    refine_min_observations: int = 60  # refinement keeps at least this many (finest) observations per image
    #: refinement's Cauchy loss scale, times the median reprojection error (0: plain least squares)
    refine_loss_scale: float = 0.5
    #: the refinement's bundle adjustment stops after this many iterations (it creeps on: iterations 30-100 moved the
    #: flower capture's cameras by under 0.01 degrees and cost 3.7 s)
    refine_max_iterations: int = 30
    undistort: bool = True  # undistort to PINHOLE when the camera model has distortion
    skip_unreadable: bool = False  # skip corrupt image files with a warning instead of failing
    ground_percentile: float = 5.0  # (no ground truth) this percentile of point heights is put at z=0
    #: (no ground truth) scale so the mean camera height is this; None keeps COLMAP's scale
    camera_height: Optional[float] = 1.6
    device: str = "auto"  # auto | cpu | cuda (SIFT extraction and matching)
    #: threads of SIFT extraction and undistortion (-1: the CPUs available, or anigs --threads); 1, 2 and 4 threads gave
    #: bit-identical outputs
    num_threads: int = -1
    #: threads of SIFT matching and geometric verification (-1: as num_threads); COLMAP's CPU matcher builds a FAISS
    #: index per image in each matching thread, and with several threads some runs matched a few pairs differently
    #: (benchmarks/README.md); one thread costs no CPU time, only wall time
    matching_num_threads: int = 1
    #: threads of mapping and bundle adjustment; 1 is bit-deterministic for a seed, more (-1: as num_threads) is faster
    #: but cameras differ slightly from run to run
    mapper_num_threads: int = 1
    #: the incremental mapper bundle-adjusts the whole model when it has grown by this factor in images or points since
    #: the last time (COLMAP: 1.1)
    ba_global_growth: float = 1.4
    #: the mapper's global bundle adjustment is repeated (filter, retriangulate, adjust) at most this many times
    #: (COLMAP: 5)
    ba_global_max_refinements: int = 2
    ba_local_max_refinements: int = 1  # same for the local bundle adjustment after each registered image (COLMAP: 2)
    #: the incremental mapper's bundle adjustments refine the lens distortion too; auto: not for SIMPLE_RADIAL/RADIAL
    #: (the refinement, or one last bundle adjustment, estimates it: a first model of a few close views cannot tell it
    #: from the focal length; on the flower capture one reached f = 2978 px, k = 10 and stalled), yes for the other
    #: models
    mapper_refine_distortion: Union[bool, str] = "auto"
    #: COLMAP random seed (>= 0): every RANSAC, two-view verification included, restarts from it for each image pair,
    #: so the results do not depend on which thread takes which pair (COLMAP's default -1 leaves it unseeded: the
    #: verified matches then change from run to run with the thread schedule)
    seed: int = 0

    WHERE: ClassVar[str] = "sfm config"
    ERROR: ClassVar[type[Exception]] = KeyError

    def mapper_holds_distortion(self) -> bool:
        """Whether the incremental mapper keeps the distortion parameters at their initial values."""
        if self.mapper_refine_distortion == "auto":
            return self.camera_model in MILD_DISTORTION_MODELS
        return not self.mapper_refine_distortion

    def validate(self) -> None:
        import pycolmap

        if self.camera_model not in pycolmap.CameraModelId.__members__:
            raise ValueError(f"sfm.camera_model {self.camera_model!r} is not a COLMAP camera model; "
                             f"choose one of {sorted(pycolmap.CameraModelId.__members__)}")
        if self.matcher not in MATCHERS:
            raise ValueError(f"sfm.matcher {self.matcher!r} not in {MATCHERS}")
        if self.mapper not in MAPPERS:
            raise ValueError(f"sfm.mapper {self.mapper!r} not in {MAPPERS}")
        if self.device not in ("auto", "cpu") and not self.device.startswith("cuda"):
            raise ValueError(f"sfm.device {self.device!r} is not auto, cpu or cuda[:N] (the run's device)")
        if not 0 < self.min_registered_fraction <= 1:
            raise ValueError(f"sfm.min_registered_fraction must be in (0, 1], got {self.min_registered_fraction}")
        if isinstance(self.mapper_restarts, bool) or not isinstance(self.mapper_restarts, int) \
                or not 0 <= self.mapper_restarts <= 64:
            raise ValueError(f"sfm.mapper_restarts must be an integer in [0, 64], got {self.mapper_restarts!r}")
        if not 0 < self.partial_min_fraction <= 1:
            raise ValueError(f"sfm.partial_min_fraction must be in (0, 1], got {self.partial_min_fraction}")
        if self.camera_height is not None and not self.camera_height > 0:
            raise ValueError(f"sfm.camera_height must be > 0 or null, got {self.camera_height}")
        if not 0 <= self.ground_percentile <= 100:
            raise ValueError(f"sfm.ground_percentile must be in [0, 100], got {self.ground_percentile}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed < 2**31 - 1024:
            raise ValueError(f"sfm.seed must be an integer in [0, 2^31 - 1024), got {self.seed!r}: COLMAP's -1 leaves "
                             "RANSAC unseeded, and the verified matches then depend on thread scheduling")
        for key in ("num_threads", "matching_num_threads", "mapper_num_threads"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, int) or v == 0 or v < -1:
                raise ValueError(f"sfm.{key} must be -1 (all cores) or >= 1, got {v!r}")
        if isinstance(self.exhaustive_max_images, bool) or not isinstance(self.exhaustive_max_images, int) \
                or self.exhaustive_max_images < 2:
            raise ValueError(f"sfm.exhaustive_max_images must be an integer >= 2, got {self.exhaustive_max_images!r}")
        if not self.exhaustive_max_comparisons > 0:
            raise ValueError(f"sfm.exhaustive_max_comparisons must be > 0, got {self.exhaustive_max_comparisons}")
        if self.sequential_similar < 0:
            raise ValueError(f"sfm.sequential_similar must be >= 0, got {self.sequential_similar}")
        if self.mapper_refine_distortion not in (True, False, "auto"):
            raise ValueError(f"sfm.mapper_refine_distortion must be true, false or 'auto', got {self.mapper_refine_distortion!r}")
        if self.refine_max_iterations < 1:
            raise ValueError(f"sfm.refine_max_iterations must be >= 1, got {self.refine_max_iterations}")
        if not self.ba_global_growth > 1:
            raise ValueError(f"sfm.ba_global_growth must be > 1, got {self.ba_global_growth}")
        for key in ("ba_global_max_refinements", "ba_local_max_refinements"):
            if getattr(self, key) < 1:
                raise ValueError(f"sfm.{key} must be >= 1, got {getattr(self, key)}")
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
        if isinstance(self.init_min_tri_angle, str) and self.init_min_tri_angle != "auto":
            raise ValueError(f"sfm.init_min_tri_angle must be 'auto' or an angle in degrees, got {self.init_min_tri_angle!r}")
        for key in ("init_min_tri_angle", "retry_init_min_tri_angle"):
            v = getattr(self, key)
            if v is not None and v != "auto" and not 0 < v < 90:
                raise ValueError(f"sfm.{key} must be in (0, 90) degrees, got {v}")
