"""``sam2`` mask backend (optional extra): SAM2 masks selected by vegetation score or point prompts.

Modes:
``auto``    SAM2's automatic mask generator; a segment is dynamic when the fraction of its
            pixels that the ``vegetation`` backend marks is >= ``min_vegetation``.
``points``  SAM2's image predictor with positive pixel prompts ``points`` [[x, y], ...]
            (pixels of the view image); the best-scoring mask of each prompt is kept.

Weights are never downloaded: ``checkpoint`` is a local ``.pt`` path (e.g.
``sam2.1_hiera_tiny.pt`` from the SAM2 release page). ``checkpoint: null`` with
``random_weights: true`` builds random weights from the config (tests only).

Install: ``SAM2_BUILD_CUDA=0 pip install --no-build-isolation sam2`` plus a torchvision build
matching the installed torch (the PyPI torchvision is a CUDA build that fails to import with
the CPU torch: sam2 imports torchvision).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from anigs.typed_config import Section
from anigs.device import get_device
from anigs.masks.frame import Frame
from anigs.masks.vegetation import VegetationConfig, vegetation_mask

INSTALL_HINT = ("install the 'sam2' extra: SAM2_BUILD_CUDA=0 pip install --no-build-isolation sam2, "
                "with a torchvision build that matches your torch (on a CPU-only torch the PyPI "
                "torchvision, a CUDA build, fails to import)")


@dataclass
class Sam2Config(Section):
    """Parameters of the SAM2 backend (config section ``masks.sam2``)."""

    HANDED = ('device',)  # set once for the whole run (anigs.config.HANDED), not in this section

    WHERE = "masks.sam2 config"

    checkpoint: str | None = None            # local SAM2 checkpoint (.pt)
    model_config: str = "configs/sam2.1/sam2.1_hiera_t.yaml"  # config name inside the sam2 package
    mode: str = "auto"                        # auto | points
    points: list = field(default_factory=list)  # [[x, y], ...] pixel prompts for mode 'points'
    min_vegetation: float = 0.5               # auto: min fraction of vegetation pixels in a segment
    points_per_side: int = 16                 # auto: prompt grid density
    device: str = "auto"                      # auto | cpu | cuda
    random_weights: bool = False              # tests only: allow checkpoint null

    def validate(self) -> None:
        if self.mode not in ("auto", "points"):
            raise ValueError(f"sam2.mode must be 'auto' or 'points', got {self.mode!r}")
        if self.mode == "points" and not self.points:
            raise ValueError("sam2.mode 'points' needs sam2.points [[x, y], ...]")



def import_sam2():
    """Import the SAM2 modules, or raise ImportError that says what to install."""
    try:
        from sam2.automatic_mask_generator import SAM2AutomaticMaskGenerator
        from sam2.build_sam import build_sam2
        from sam2.sam2_image_predictor import SAM2ImagePredictor
    except Exception as exc:  # torchvision's failure is a RuntimeError/AttributeError, not ImportError
        raise ImportError(f"the sam2 mask backend cannot import sam2 ({type(exc).__name__}: {exc}); "
                          + INSTALL_HINT) from exc
    return build_sam2, SAM2AutomaticMaskGenerator, SAM2ImagePredictor


class Sam2Backend:
    """Callable mask backend around a SAM2 model."""

    def __init__(self, cfg: Sam2Config, vegetation: VegetationConfig | None = None):
        if cfg.checkpoint is None and not cfg.random_weights:
            raise ValueError("sam2 backend: set masks.sam2.checkpoint to a local SAM2 checkpoint (.pt), "
                             "e.g. sam2.1_hiera_tiny.pt from the SAM2 release page")
        if cfg.checkpoint is not None and not Path(cfg.checkpoint).is_file():
            raise FileNotFoundError(f"sam2 backend: checkpoint not found: {cfg.checkpoint} "
                                    "(download a SAM2 checkpoint and point masks.sam2.checkpoint at it)")
        build_sam2, AutoGen, Predictor = import_sam2()
        dev = get_device(cfg.device)
        model = build_sam2(cfg.model_config, cfg.checkpoint, device=str(dev), apply_postprocessing=False)
        self.cfg, self.veg = cfg, vegetation or VegetationConfig()
        if cfg.mode == "auto":
            self.gen = AutoGen(model, points_per_side=cfg.points_per_side)
        else:
            self.pred = Predictor(model)

    def __call__(self, frame: Frame) -> dict[str, np.ndarray]:
        img8 = (np.clip(frame.image, 0, 1) * 255 + 0.5).astype(np.uint8)
        h, w = img8.shape[:2]
        out = np.zeros((h, w), bool)
        if self.cfg.mode == "auto":
            veg = vegetation_mask(frame.image, self.veg, frame.name)
            for seg in self.gen.generate(img8):
                m = np.asarray(seg["segmentation"], bool)
                if m.any() and veg[m].mean() >= self.cfg.min_vegetation:
                    out |= m
        else:
            self.pred.set_image(img8)
            for x, y in self.cfg.points:
                masks, scores, _ = self.pred.predict(point_coords=np.array([[x, y]], np.float32),
                                                     point_labels=np.array([1]), multimask_output=True)
                out |= np.asarray(masks[int(np.argmax(scores))]) > 0
        return {"dynamic": out}


def build(config: dict | Sam2Config | None = None, vegetation: dict | VegetationConfig | None = None,
          **kwargs) -> Sam2Backend:
    """Registry entry: a config dict / dataclass, or the dataclass fields as keywords."""
    cfg = config if isinstance(config, Sam2Config) else Sam2Config.from_dict({**(config or {}), **kwargs})
    veg = vegetation
    if isinstance(vegetation, dict):
        veg = VegetationConfig.from_dict(vegetation)
    return Sam2Backend(cfg, veg)
