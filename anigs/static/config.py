"""The ``static`` config section: :class:`StaticConfig` (the static fit's hyperparameters and its budget)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from anigs.static.budget import parse_budget
from anigs.static.densify import DensifyConfig
from anigs.static.regularize import RegularizeConfig
from anigs.typed_config import Section

#: the frames an imported splat may be read in (``static.imported.frame``; :mod:`anigs.static.imported`)
IMPORT_FRAMES = ("auto", "cameras", "sfm", "colmap", "opensplat", "nerfstudio", "gsplat")


@dataclass
class ImportConfig(Section):
    """A splat trained elsewhere (the scene's ``splat:``), imported instead of fitted (config ``static.imported``)."""

    HANDED = ('background',)  # set once for the whole run (anigs.config.HANDED), not in this section

    #: the splat's frame: auto (the trainer's files beside the splat first: its cameras.json, nerfstudio's
    #: dataparser_transforms.json; then the known trainers' conventions, each checked by rendering the photos);
    #: cameras (the cameras.json beside it), sfm (the sfm folder's frame as it is), colmap (the COLMAP project's
    #: own frame: INRIA 3DGS), opensplat (its centred and scaled poses), nerfstudio, gsplat (its normalize_world_space)
    frame: str = "auto"
    #: refuse the splat when it renders the training photos below this PSNR (dB) ...
    min_psnr: float = 14.0
    #: ... or less than this many dB above a flat image of each photo's mean colour (what an empty or shifted
    #: scene scores)
    min_gain_db: float = 3.0
    #: the photos are compared at most this size on the longest side (px; 0: as the sfm folder holds them)
    eval_max_side: int = 640
    #: what the splat is rendered onto for the comparison: "trainer" (INRIA's cfg_args white_background,
    #: OpenSplat's fixed colour, else black) or an RGB in [0,1]
    background: tuple[float, float, float] | str = "trainer"

    WHERE: ClassVar[str] = "static.imported config"

    def validate(self) -> None:
        if self.frame not in IMPORT_FRAMES:
            raise ValueError(f"static.imported.frame must be one of {list(IMPORT_FRAMES)}, got {self.frame!r}")
        if self.eval_max_side < 0:
            raise ValueError(f"static.imported.eval_max_side must be >= 0 (0: as stored), got {self.eval_max_side}")
        if isinstance(self.background, str):
            if self.background != "trainer":
                raise ValueError(f"static.imported.background must be 'trainer' or 3 values in [0,1], "
                                 f"got {self.background!r}")
        elif len(self.background) != 3 or not all(0 <= x <= 1 for x in self.background):
            raise ValueError(f"static.imported.background must be 'trainer' or 3 values in [0,1], got {self.background}")


@dataclass
class SparseConfig(Section):
    """Weight-free help for captures that see each part from few photos (config ``static.sparse``): each
    technique its own switch (their held-out figures per capture: README, "Sparse walks")."""

    #: DropGaussian (Park et al., CVPR 2025): at each training step every Gaussian is left out with a rate
    #: rising linearly from 0 to this at the last step, the kept ones' opacity divided by (1 - rate), so that
    #: Gaussians behind the front ones get gradients too; the held-out evaluation and every later render use
    #: all of them. 0: off
    drop_rate: float = 0.0
    #: start from the SfM points plus points triangulated from neighbouring pairs of training photos
    #: (:mod:`anigs.static.pair_points`: guided SIFT matches under the known poses, relaxed two-view
    #: triangulation); photos only (a synthetic scene, with a fixed background, starts from its SfM points)
    pair_points: bool = False
    pair_neighbours: int = 5  # each training photo is paired with this many nearest photos (by camera centre)
    #: start from the SfM points plus the training photos' plane-sweep stereo depth where neighbouring photos
    #: agree (:mod:`anigs.static.stereo_points`); photos only, as pair_points (their share: pair_share)
    stereo_points: bool = False
    #: at most this share of the plan's Gaussian budget starts at pair (or stereo) points (an even subsample): the rest is
    #: left to densification (the castle's 9 photos give 30,000 points, its whole auto budget)
    pair_share: float = 0.5

    #: weight of the warp loss (:mod:`anigs.static.warp`): the render's depth of a training photo must carry
    #: its nearest training photos' colours onto it (mean L1, the per-pixel minimum over the neighbours); 0: off
    warp_weight: float = 0.0
    warp_neighbours: int = 2  # the photos each training photo is warped from

    WHERE: ClassVar[str] = "static.sparse config"

    def validate(self) -> None:
        if not 0 <= self.drop_rate < 1:
            raise ValueError(f"static.sparse.drop_rate must be in [0, 1), got {self.drop_rate}")
        if not 0 < self.pair_share <= 1:
            raise ValueError(f"static.sparse.pair_share must be in (0, 1], got {self.pair_share}")
        if self.warp_weight < 0 or self.warp_neighbours < 1:
            raise ValueError(f"static.sparse.warp_weight must be >= 0 and warp_neighbours >= 1, got "
                             f"{self.warp_weight} and {self.warp_neighbours}")
        if self.pair_neighbours < 1:
            raise ValueError(f"static.sparse.pair_neighbours must be >= 1, got {self.pair_neighbours}")


@dataclass
class StaticConfig(Section):
    """Static fit hyperparameters (the ``static`` config section)."""

    HANDED = ('seed', 'device', 'background')  # set once for the whole run (anigs.config.HANDED), not in this section

    WHERE = "static config"

    #: the one dial: a level (fast, auto, quality: steps and Gaussians follow the capture's photos and pixels)
    #: or minutes on this machine; the plan and its estimated time are logged before the fit starts
    budget: str | float = "auto"
    iterations: int | None = None  # optimisation steps (null: from the budget; the fit may end earlier, plateau_db)
    seed: int = 0  # seeds view order, split sampling and everything else
    sh_degree: int = 3  # final SH degree (0..3)
    sh_increase_every: int = 300  # raise the active SH degree by one every this many steps
    #: "random": a new random colour behind the splats at every step, so that only what the photos show
    #: is opaque and unobserved space stays transparent (views composite it onto final.background);
    #: or a fixed RGB in [0,1] (a synthetic scene's sky: its photos were rendered onto it)
    background: tuple[float, float, float] | str = "random"
    holdout_every: int = 8  # images i with i % holdout_every == 0 are held out (0 = none)
    lr_means: float = 1.6e-4  # initial position lr, times the scene extent
    lr_means_final: float = 1.6e-6  # final position lr, times the scene extent
    lr_sh_dc: float = 2.5e-3  # learning rate of the DC SH coefficients
    lr_sh_rest: float = 2.5e-3 / 20  # learning rate of the higher-order SH coefficients
    lr_opacity: float = 5e-2  # learning rate of the opacity logits
    lr_scales: float = 5e-3  # learning rate of the log-scales
    lr_quats: float = 1e-3  # learning rate of the rotations
    ssim_weight: float = 0.2  # loss = (1-w) L1 + w (1 - SSIM)
    #: weight of the depth loss at the first step: mean |log(render depth / SfM depth)| at the SfM points each
    #: training photo observes (the sfm stage's tracks.npz; photos only: a synthetic scene gets no tracks); 0: off
    depth_weight: float = 0.0
    depth_weight_final: float = 0.0  # its weight at the last step (log-linear in between; 0: linear to 0)
    depth_tolerance: float = 0.0  # depth errors up to this log ratio (0.02: 2%) cost nothing: SfM depths are not exact
    #: learning rate of a per-training-photo affine colour map (3x3 + 3, identity at the start) applied to the
    #: render before the loss (exposure, white balance); held-out photos and every later render use none; 0: off
    exposure_lr: float = 0.0
    init_opacity: float = 0.1  # opacity of the initial Gaussians
    #: the fit's photos are downscaled to at most this longest side (px; 0: as captured; null: the budget
    #: level's: auto 640, fast and quality as captured); held-out and train PSNR are measured at that size
    max_side: int | None = None
    #: at most this share of the Gaussian budget starts on a far sphere where photos show what SfM did not
    #: triangulate above the horizon (the sky, distant background); with background "random" only (a fixed
    #: background, a synthetic scene's sky, is the far field itself); 0: none
    far_share: float = 0.1
    eval_every: int | None = None  # held-out PSNR every this many steps (null: about 8 points over the fit; 0 = end only)
    #: stop once densification is over and the held-out PSNR gained less than this (dB) since the
    #: previous evaluation (0: never stop early)
    plateau_db: float = 0.05
    checkpoint_every: int = 500  # write the last good PLY every this many steps (with checkpoint_path)
    device: str = "auto"  # torch device: auto picks CUDA when present (the workflow passes the global device)
    backend: str = "auto"  # rasterizer backend
    #: densification strategy (clone, split, prune, opacity reset)
    densify: DensifyConfig = field(default_factory=DensifyConfig)
    regularize: RegularizeConfig = field(default_factory=RegularizeConfig)  # needles / unresolved splats
    #: a splat trained elsewhere (the scene's ``splat:``): its frame and the check against the photos
    imported: ImportConfig = field(default_factory=ImportConfig)
    #: weight-free help for sparse captures: DropGaussian, a denser start from photo pairs
    sparse: SparseConfig = field(default_factory=SparseConfig)

    def validate(self) -> None:
        if not isinstance(self.background, str):
            self.background = tuple(float(x) for x in self.background)
        parse_budget(self.budget)
        if self.iterations is not None and self.iterations < 0:
            raise ValueError(f"static.iterations must be >= 0, got {self.iterations}")
        if self.eval_every is not None and self.eval_every < 0:
            raise ValueError(f"static.eval_every must be >= 0, got {self.eval_every}")
        if self.plateau_db < 0:
            raise ValueError(f"static.plateau_db must be >= 0, got {self.plateau_db}")
        if not 0 <= self.sh_degree <= 3:
            raise ValueError(f"static.sh_degree must be in 0..3, got {self.sh_degree}")
        if self.sh_increase_every < 1:
            raise ValueError(f"static.sh_increase_every must be >= 1, got {self.sh_increase_every}")
        if isinstance(self.background, str):
            if self.background != "random":
                raise ValueError(f"static.background must be 'random' or 3 values in [0,1], got {self.background!r}")
        elif len(self.background) != 3 or not all(0 <= x <= 1 for x in self.background):
            raise ValueError(f"static.background must be 'random' or 3 values in [0,1], got {self.background}")
        if self.holdout_every < 0 or self.holdout_every == 1:
            raise ValueError(f"static.holdout_every must be 0 (no holdout) or >= 2, got {self.holdout_every}")
        if not 0 <= self.ssim_weight <= 1:
            raise ValueError(f"static.ssim_weight must be in [0,1], got {self.ssim_weight}")
        if self.max_side is not None and self.max_side < 0:
            raise ValueError(f"static.max_side must be >= 0 (0: as captured), got {self.max_side}")
        if not 0 <= self.far_share < 1:
            raise ValueError(f"static.far_share must be in [0, 1), got {self.far_share}")
        if self.depth_weight < 0 or self.depth_weight_final < 0:
            raise ValueError(f"static.depth_weight and depth_weight_final must be >= 0, got {self.depth_weight} "
                             f"and {self.depth_weight_final}")
        if self.depth_tolerance < 0:
            raise ValueError(f"static.depth_tolerance must be >= 0, got {self.depth_tolerance}")
        if self.exposure_lr < 0:
            raise ValueError(f"static.exposure_lr must be >= 0 (0: off), got {self.exposure_lr}")
        if not 0 < self.init_opacity < 1:
            raise ValueError(f"static.init_opacity must be in (0,1), got {self.init_opacity}")
        self.densify.validate()
        self.regularize.validate()
        self.imported.validate()
        self.sparse.validate()
