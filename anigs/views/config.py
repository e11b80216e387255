"""The ``views`` stage's parameters (:class:`ViewsConfig`)."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

from anigs import geometry
from anigs.typed_config import Section
from anigs.render.visibility import VisibilityConfig
from anigs.views.content import ContentRule

log = logging.getLogger("anigs.views")


@dataclass
class ViewsConfig(Section):
    """Parameters of the view queue (config section ``views``)."""

    HANDED = ('seed', 'background')  # set once for the whole run (anigs.config.HANDED), not in this section

    WHERE = "views config"

    num_locations: int = 4            # N camera locations
    directions: list = field(default_factory=lambda: [0.0, 90.0, -90.0])  # yaw order per location (deg)
    fov_deg: float = 95.0             # horizontal field of view of every view
    width: int = 256                  # view image width
    height: int = 192                 # view image height
    pitch_deg: float = 0.0            # elevation of the views (negative looks down)
    up: str = "z"                     # "z" or "auto" (estimated from the candidate cameras)
    forward: str = "best"             # yaw-0 heading: best | centroid | camera
    heading_step_deg: float = 5.0     # resolution of the 'best' heading search
    jitter_std: float = 0.0           # std of horizontal jitter of extra candidates (world units)
    jitter_copies: int = 0            # jittered copies per camera centre
    visibility_power: float = 1.0     # FPS score = min distance * (visible fraction)^power
    max_candidates: int = 64          # more candidates are thinned by farthest-point sampling first
    visibility: str = "weight"        # coverage test: weight | depth | frustum
    min_weight: float = 0.05          # 'weight' test: min summed blending weight (pixels)
    rel_tol: float = 0.03             # 'depth' test: relative depth tolerance
    scale_tol: float = 2.0            # 'depth' test: tolerance in Gaussian max-scales
    min_overlap: float = 0.0          # warn when a view's overlap with previous views is <= this
    seed: int = 0                     # jitter seed
    layout: str = "auto"              # auto | walk | forward | orbit (auto: classified from the cameras)
    min_coverage: float = 0.8         # min fraction of a view's pixels that see the fitted scene
    coverage_alpha: float = 0.5       # a pixel sees the scene when its accumulated alpha is >= this
    min_observations: int = 2         # only Gaussians visible in >= this many capture photos count
    pitch_step_deg: float = 10.0      # replacement: pitch a failing direction down in these steps
    max_pitch_drop_deg: float = 30.0  # ... by at most this much
    yaw_steps: list = field(default_factory=lambda: [0.33, 0.67, 1.0])  # then move yaw this share towards the ROI
    extra_locations: int = 8          # extra candidate locations tried for directions no location passes
    match_capture_fov: bool = True    # forward/orbit layouts: FOV at most the capture photos' median FOV
    #: a view is queued only if the ROI covers >= this share of its pixels (pixels the masks stage would mark: ROI
    #: carries >= 0.5 of the rendered alpha, alpha >= 0.3); 0 queues every view
    min_dynamic_fraction: float = 0.005
    topdown_size: int = 720         # pixels of the top-down map (views/topdown.png)
    #: min share of a view's pixels dominated by sharp Gaussians (anigs.views.content); 0 disables the test
    min_content: float = 0.5
    #: a capture photo resolves a Gaussian when its largest std dev spans <= this x its width
    sharp_fraction: float = 0.05
    min_sharp_observations: int = 2   # a sharp Gaussian is resolved by >= this many capture photos
    footprint_ratio: float = 6.0      # ... its largest scale is <= this x the median of its 16 nearest neighbours'
    #: ... and its centre lies within this x the local spacing of the nearest SfM point (with --points)
    near_points: float = 3.0
    #: ... and counts for a view only when the finest pixel footprint of a photo seeing it is <= this x the view's
    #: (a view closer than the photos resolve shows blur); 0: off
    max_sampling_ratio: float = 1.0
    #: min share of a view's render within 4 px of an edge (abs Laplacian of grey > 6 at 0-255); 0: recorded, not
    #: applied
    min_edge_share: float = 0.0
    #: a view's moving region must be >= this x as sharp as the sharpest photo that sees it shows it (band sharpness
    #: at the view's sampling, anigs.views.motion); a failing direction is replaced; 0: recorded, not applied
    min_motion_sharpness: float = 0.7
    #: max share of a view's pixels that no Gaussian covers (rendered alpha < 0.5: the background shows); 1: recorded,
    #: not applied
    max_unobserved: float = 0.02
    #: directions that no location shows sharply enough (min_motion_sharpness) are filled with views at the poses of
    #: the photos that show the moving region best, and views.json says where more photos would help
    photo_pose_fallback: bool = True
    #: two directions queued at one location differ by at least this angle (deg, yaw and pitch together): a
    #: replacement closer to one already queued there is skipped (the street walk queued three near-copies of one
    #: view, 94-99% overlapping, when every planned yaw fell back to the same best direction; the planned yaws are
    #: 90 deg apart, the walk views 95 deg wide); 0: off
    min_separation_deg: float = 30.0
    #: render background of the edge figure (the scene's sky colour)
    background: list = field(default_factory=lambda: [0.0, 0.0, 0.0])

    def validate(self) -> None:
        if self.layout not in ("auto",) + geometry.LAYOUTS:
            raise ValueError(f"views.layout must be 'auto' or one of {geometry.LAYOUTS}, got {self.layout!r}")
        if not 0.0 <= self.min_coverage <= 1.0 or not 0.0 < self.coverage_alpha <= 1.0:
            raise ValueError(f"views.min_coverage must be in [0, 1] and coverage_alpha in (0, 1], "
                             f"got {self.min_coverage}, {self.coverage_alpha}")
        if not 0.0 <= self.min_dynamic_fraction <= 1.0:
            raise ValueError(f"views.min_dynamic_fraction must be in [0, 1], got {self.min_dynamic_fraction}")
        if self.min_observations < 0 or self.extra_locations < 0:
            raise ValueError("views.min_observations and views.extra_locations must be >= 0")
        if self.pitch_step_deg <= 0 or self.max_pitch_drop_deg < 0:
            raise ValueError("views.pitch_step_deg must be > 0 and max_pitch_drop_deg >= 0")
        self.yaw_steps = [float(t) for t in self.yaw_steps]
        if any(not 0.0 < t <= 1.0 for t in self.yaw_steps):
            raise ValueError(f"views.yaw_steps must be in (0, 1], got {self.yaw_steps}")
        if self.num_locations < 1:
            raise ValueError(f"views.num_locations must be >= 1, got {self.num_locations}")
        if not self.directions:
            raise ValueError("views.directions must list at least one yaw")
        self.directions = [float(d) for d in self.directions]
        if self.width < 8 or self.height < 8:
            raise ValueError(f"views: resolution {self.width}x{self.height} is too small (min 8x8)")
        if self.up not in ("z", "auto"):
            raise ValueError(f"views.up must be 'z' or 'auto', got {self.up!r}")
        if self.forward not in ("best", "centroid", "camera"):
            raise ValueError(f"views.forward must be 'best', 'centroid' or 'camera', got {self.forward!r}")
        if self.jitter_copies < 0 or self.jitter_std < 0:
            raise ValueError("views.jitter_copies and views.jitter_std must be >= 0")
        if self.heading_step_deg <= 0:
            raise ValueError(f"views.heading_step_deg must be > 0, got {self.heading_step_deg}")
        VisibilityConfig(mode=self.visibility)  # validates the mode name
        if not 0.0 <= self.min_content <= 1.0 or not 0.0 <= self.min_edge_share <= 1.0:
            raise ValueError(f"views.min_content and views.min_edge_share must be in [0, 1], "
                             f"got {self.min_content}, {self.min_edge_share}")
        if self.min_motion_sharpness < 0 or not 0.0 <= self.max_unobserved <= 1.0:
            raise ValueError(f"views.min_motion_sharpness must be >= 0 (0: off) and max_unobserved in [0, 1], got "
                             f"{self.min_motion_sharpness}, {self.max_unobserved}")
        if not 0.0 <= self.min_separation_deg <= 180.0:
            raise ValueError(f"views.min_separation_deg must be in [0, 180], got {self.min_separation_deg}")
        if self.max_sampling_ratio < 0:
            raise ValueError(f"views.max_sampling_ratio must be >= 0 (0: off), got {self.max_sampling_ratio}")
        if self.sharp_fraction <= 0 or self.footprint_ratio <= 0 or self.near_points <= 0 or self.min_sharp_observations < 0:
            raise ValueError("views.sharp_fraction, footprint_ratio and near_points must be > 0 and "
                             "min_sharp_observations >= 0")
        if len(self.background) != 3 or not all(0.0 <= float(x) <= 1.0 for x in self.background):
            raise ValueError(f"views.background must be 3 values in [0, 1], got {self.background}")
        self.background = [float(x) for x in self.background]

    def content_rule(self):
        """The sharp-Gaussian test and content figure (:class:`anigs.views.content.ContentRule`)."""
        return ContentRule(min_content=self.min_content, sharp_fraction=self.sharp_fraction,
                           min_sharp_observations=self.min_sharp_observations,
                           footprint_ratio=self.footprint_ratio, near_points=self.near_points,
                           alpha=self.coverage_alpha, min_weight=self.min_weight,
                           max_sampling_ratio=self.max_sampling_ratio,
                           min_motion_sharpness=self.min_motion_sharpness, max_unobserved=self.max_unobserved)

    def visibility_config(self) -> VisibilityConfig:
        return VisibilityConfig(mode=self.visibility, rel_tol=self.rel_tol, scale_tol=self.scale_tol,
                                min_weight=self.min_weight)
