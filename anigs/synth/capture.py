"""The synthetic capture: a casual hand-held camera path through the garden, rendered at t=0.

``write_capture(cfg, out)`` writes into the capture stage's folder (``out``: its ``Outputs``,
:mod:`anigs.stages.capture`, which names the files), by key:

    images          img_000.png ...: the photos (what SfM sees)
    gt_cameras      ground-truth cameras (anigs.cameras format)
    gt_gaussians    ground-truth Gaussians (standard 3DGS layout, SH degree 0)
    gt_labels       [N] int32 semantic label per Gaussian (scene.LABELS)
    gt_anchors      [N,3] float32 sway anchor per Gaussian
    gt_motion       motion parameters + label/effect tables
    gt_scene        the full config used, label counts, timing

all atomically. The path (``capture.layout``):

``walk`` (default)  most images on an irregular loop around the lawn looking inwards (with slow
                    yaw/pitch swings), the rest walking up the garden path towards the building;
``forward``         a forward-facing (LLFF-style) close-up of the west flower bed in front of the
                    facade: a grid of positions 1 m in front of it, all looking the same way;
``orbit``           an inward orbit around the east tree, every camera looking at its crown;
``facade``          a walk along the building looking up at it (pitch 25-45 degrees up).

Positions and orientations are jittered like a hand-held camera. ``capture.roll`` turns photos
sideways (a portrait photo stored without its EXIF rotation): ``portrait`` rolls every camera
by 90 degrees about its optical axis, ``mixed`` every other one (the image keeps its size).
The scene, labels and wind motion are the same for every layout.
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch

from anigs.typed_config import check_in, from_dict
from anigs.cameras import Camera, intrinsics_from_fov, look_at, save_cameras
from anigs.io import StageFolder, atomic_path, write_json
from anigs.render import render_gaussians
from anigs.synth.motion import MotionParams, motion_tables
from anigs.synth.build import build_scene
from anigs.synth.scene import BEDS, LABELS, SKY, TREE_SITES, Y1, SceneConfig, path_x
from anigs.video import save_png

log = logging.getLogger(__name__)

LOOP_CENTER = (0.0, -0.3)
LOOP_RADII = (3.3, 2.4)
CAPTURE_LAYOUTS = ("walk", "forward", "orbit", "facade")
CAPTURE_ROLLS = ("none", "portrait", "mixed")


@dataclass
class CameraPathConfig:
    """Camera path and image parameters (config section ``synthetic.capture``)."""

    num_images: int = 48  # photos in the capture
    width: int = 320
    height: int = 240
    fov_deg: float = 62.0  # horizontal field of view
    eye_height: float = 1.6  # camera height above the ground (m)
    pos_jitter: float = 0.06  # hand-held position noise (m, std)
    rot_jitter_deg: float = 1.5  # hand-held orientation noise (degrees, std)
    walk_fraction: float = 0.25  # share of the images taken walking up the path (rest: loop)
    background: tuple = SKY  # sky colour (RGB in [0,1])
    layout: str = "walk"  # walk | forward | orbit | facade (see module docstring)
    roll: str = "none"  # none | portrait | mixed: photos stored sideways (rolled 90 degrees)

    def __post_init__(self) -> None:
        if self.layout not in CAPTURE_LAYOUTS:
            raise ValueError(f"capture.layout must be one of {CAPTURE_LAYOUTS}, got {self.layout!r}")
        if self.roll not in CAPTURE_ROLLS:
            raise ValueError(f"capture.roll must be one of {CAPTURE_ROLLS}, got {self.roll!r}")
        check_in("capture.num_images", self.num_images, 3, 1000)
        if self.width < 16 or self.height < 16:
            raise ValueError(f"capture image size must be >= 16x16, got {self.width}x{self.height}")
        check_in("capture.fov_deg", self.fov_deg, 20, 120)
        check_in("capture.eye_height", self.eye_height, 0.5, 3)
        check_in("capture.walk_fraction", self.walk_fraction, 0, 0.6)
        if self.pos_jitter < 0 or self.rot_jitter_deg < 0:
            raise ValueError("capture.pos_jitter and capture.rot_jitter_deg must be >= 0")
        self.background = tuple(float(v) for v in self.background)
        if len(self.background) != 3 or not all(0 <= v <= 1 for v in self.background):
            raise ValueError(f"capture.background must be 3 values in [0,1], got {self.background}")

    @staticmethod
    def from_dict(d: dict | None) -> "CameraPathConfig":
        return from_dict(CameraPathConfig, d, "synthetic.capture", check_types=True)


@dataclass
class SynthConfig:
    """Everything under ``synthetic:`` in a scene file: seed, scene, capture, motion."""

    seed: int = 0
    scene: SceneConfig = field(default_factory=SceneConfig)
    capture: CameraPathConfig = field(default_factory=CameraPathConfig)
    motion: MotionParams = field(default_factory=MotionParams)

    @staticmethod
    def from_dict(d: dict | None) -> "SynthConfig":
        d = dict(d or {})
        allowed = {"seed", "scene", "capture", "motion"}
        unknown = sorted(set(d) - allowed)
        if unknown:
            hint = " (pass the scene file's `synthetic` section, not the whole file)" if "synthetic" in unknown else ""
            raise ValueError(f"synthetic: unknown key(s) {unknown}; allowed: {sorted(allowed)}{hint}")
        seed = d.get("seed", 0)
        if not isinstance(seed, int) or isinstance(seed, bool):
            raise ValueError(f"synthetic.seed: expected an int, got {seed!r}")
        return SynthConfig(seed, SceneConfig.from_dict(d.get("scene")), CameraPathConfig.from_dict(d.get("capture")),
                           MotionParams.from_dict(d.get("motion")))

    def to_dict(self) -> dict:
        cap = asdict(self.capture)
        cap["background"] = list(self.capture.background)
        for key, default in (("layout", "walk"), ("roll", "none")):  # the default capture's scene.json stays as it was
            if cap[key] == default:
                del cap[key]
        return {"seed": self.seed, "scene": asdict(self.scene), "capture": cap, "motion": self.motion.to_dict()}


def _camera(eye: np.ndarray, yaw: float, pitch: float, roll: float, K: np.ndarray, cfg: CameraPathConfig,
            name: str) -> Camera:
    fwd = np.array([math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), math.sin(pitch)])
    V = look_at(eye, eye + fwd)
    c, s = math.cos(roll), math.sin(roll)
    Rr = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    V[:3, :3] = Rr @ V[:3, :3]
    V[:3, 3] = Rr @ V[:3, 3]
    return Camera(K, V, cfg.width, cfg.height, name)


def camera_path(cfg: CameraPathConfig | None = None, seed: int = 0) -> list[Camera]:
    """The capture cameras of ``cfg.layout`` (deterministic for ``seed``), rolled by ``cfg.roll``."""
    cfg = cfg or CameraPathConfig()
    if cfg.layout == "walk":
        cams = walk_path(cfg, seed)
    else:
        cams = {"forward": forward_path, "orbit": orbit_path, "facade": facade_path}[cfg.layout](cfg, seed)
    if cfg.roll != "none":
        cams = [roll_camera(c, 90.0) if cfg.roll == "portrait" or i % 2 == 1 else c for i, c in enumerate(cams)]
    return cams


def roll_camera(cam: Camera, deg: float) -> Camera:
    """``cam`` rolled by ``deg`` about its optical axis (positive: the image content turns clockwise)."""
    r = math.radians(deg)
    c, s = math.cos(r), math.sin(r)
    Rr = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    V = cam.viewmat.copy()
    V[:3, :3] = Rr @ V[:3, :3]
    V[:3, 3] = Rr @ V[:3, 3]
    return Camera(cam.K.copy(), V, cam.width, cam.height, cam.name)


def _jittered(rng: np.random.Generator, cfg: CameraPathConfig, eye: np.ndarray, target: np.ndarray, K: np.ndarray,
              name: str) -> Camera:
    """Hand-held camera at ``eye`` (+ position noise) looking at ``target`` (+ orientation noise)."""
    eye = eye + rng.normal(0, 1, 3) * np.array([cfg.pos_jitter, cfg.pos_jitter, 0.5 * cfg.pos_jitter])
    d = np.asarray(target, float) - eye
    jr = math.radians(cfg.rot_jitter_deg)
    yaw = math.atan2(d[1], d[0]) + rng.normal(0, jr)
    pitch = math.atan2(d[2], math.hypot(d[0], d[1])) + rng.normal(0, jr)
    return _camera(eye, yaw, pitch, rng.normal(0, jr), K, cfg, name)


def forward_path(cfg: CameraPathConfig, seed: int = 0) -> list[Camera]:
    """Forward-facing close-up of the west flower bed: a 2-row grid of positions 1 m in front of
    it, 0.9-1.2 m high, all looking north at the bed (about 25 degrees down)."""
    rng = np.random.default_rng(int(seed) + 104729)
    K = intrinsics_from_fov(cfg.fov_deg, cfg.width, cfg.height)
    x0, x1, y0, y1 = BEDS[0]
    cols = max(int(math.ceil(cfg.num_images / 2)), 1)
    cams: list[Camera] = []
    for i in range(cfg.num_images):
        r, c = divmod(i, cols)
        x = -3.9 + 1.6 * (c + 0.5) / cols
        eye = np.array([x, y0 - 1.0, 0.9 + 0.3 * r])
        target = np.array([x + 0.15 * math.sin(1.7 * i), 0.5 * (y0 + y1), 0.25])
        cams.append(_jittered(rng, cfg, eye, target, K, f"img_{i:03d}.png"))
    return cams


ORBIT_TREE = TREE_SITES[1]


def orbit_path(cfg: CameraPathConfig, seed: int = 0) -> list[Camera]:
    """Inward orbit around the east tree (ellipse 1.75 x 2.4 m, inside the fence), 1.3 m high,
    every camera looking at the crown base (1.9 m)."""
    rng = np.random.default_rng(int(seed) + 1299709)
    K = intrinsics_from_fov(cfg.fov_deg, cfg.width, cfg.height)
    tx, ty = ORBIT_TREE
    cams: list[Camera] = []
    for i in range(cfg.num_images):
        th = 2 * math.pi * (i + rng.uniform(-0.2, 0.2)) / cfg.num_images
        eye = np.array([tx + 1.75 * math.cos(th), ty + 2.4 * math.sin(th), 1.3])
        cams.append(_jittered(rng, cfg, eye, np.array([tx, ty, 1.9]), K, f"img_{i:03d}.png"))
    return cams


def facade_path(cfg: CameraPathConfig, seed: int = 0) -> list[Camera]:
    """A walk along the building looking up at it: 1.5-3 m in front of the facade, eye height,
    pitched 25-45 degrees up, headings within +-30 degrees of the facade normal."""
    rng = np.random.default_rng(int(seed) + 15485863)
    K = intrinsics_from_fov(cfg.fov_deg, cfg.width, cfg.height)
    cams: list[Camera] = []
    for i in range(cfg.num_images):
        s = (i + 0.5) / cfg.num_images
        eye = np.array([-3.5 + 7.0 * s, Y1 - 1.5 - 1.5 * rng.uniform(), cfg.eye_height])
        head = math.pi / 2 + math.radians(30.0) * math.sin(2 * math.pi * s + 0.4)
        pitch = math.radians(25.0 + 20.0 * rng.uniform())
        dist = 3.0
        target = eye + dist * np.array([math.cos(pitch) * math.cos(head), math.cos(pitch) * math.sin(head),
                                        math.sin(pitch)])
        cams.append(_jittered(rng, cfg, eye, target, K, f"img_{i:03d}.png"))
    return cams


def walk_path(cfg: CameraPathConfig, seed: int = 0) -> list[Camera]:
    """The default hand-held path (deterministic for ``seed``): a loop, then a walk up the path."""
    rng = np.random.default_rng(int(seed) + 7919)
    K = intrinsics_from_fov(cfg.fov_deg, cfg.width, cfg.height)
    n_walk = int(round(cfg.walk_fraction * cfg.num_images))
    n_loop = cfg.num_images - n_walk
    jr = math.radians(cfg.rot_jitter_deg)
    cams: list[Camera] = []
    cx, cy = LOOP_CENTER
    for i in range(n_loop):  # irregular loop, starting in the south, counter-clockwise
        th = -math.pi / 2 + 2 * math.pi * (i + rng.uniform(-0.25, 0.25)) / n_loop
        rx = LOOP_RADII[0] * (1 + 0.06 * math.sin(2 * th + 0.4))
        ry = LOOP_RADII[1] * (1 + 0.06 * math.sin(3 * th + 1.0))
        eye = np.array([cx + rx * math.cos(th), cy + ry * math.sin(th),
                        cfg.eye_height + 0.05 * math.sin(5 * th)])
        eye += rng.normal(0, 1, 3) * np.array([cfg.pos_jitter, cfg.pos_jitter, 0.5 * cfg.pos_jitter])
        inward = math.atan2(cy - eye[1], cx - eye[0])
        yaw = inward + 0.45 * math.sin(2 * th + 0.5) + rng.normal(0, jr)
        pitch = -0.2 - 0.06 * math.sin(3 * th) + rng.normal(0, jr)
        cams.append(_camera(eye, yaw, pitch, rng.normal(0, jr), K, cfg, f"img_{len(cams):03d}.png"))
    for j in range(n_walk):  # walk up the garden path towards the door
        y = -4.2 + 4.8 * (j + rng.uniform(-0.2, 0.2)) / max(n_walk - 1, 1)
        eye = np.array([float(path_x(y)) + 0.15 * math.sin(1.3 * y), y, cfg.eye_height])
        eye += rng.normal(0, 1, 3) * np.array([cfg.pos_jitter, cfg.pos_jitter, 0.5 * cfg.pos_jitter])
        yaw = math.pi / 2 + 0.35 * math.sin(1.1 * y + 0.3) + rng.normal(0, jr)
        pitch = -0.24 + 0.05 * math.sin(2.3 * y) + rng.normal(0, jr)
        cams.append(_camera(eye, yaw, pitch, rng.normal(0, jr), K, cfg, f"img_{len(cams):03d}.png"))
    return cams


def render_image(gaussians, camera: Camera, background=SKY) -> np.ndarray:
    """Render one photo: float32 [H,W,3] in [0,1]."""
    with torch.no_grad():
        rgb, _, _ = render_gaussians(gaussians, camera, background=torch.tensor(background, dtype=torch.float32))
    return rgb.clamp(0, 1).cpu().numpy()


def _save_npy(path: Path, arr: np.ndarray) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.save(fh, arr)


def write_capture(cfg: SynthConfig | None, out: StageFolder) -> dict:
    """Build the scene, render the capture at t=0 and write images + ground truth (see module doc).

    Returns a summary dict (counts, timing, image names).
    """
    cfg = cfg or SynthConfig()
    img_dir = out.path("images")
    t0 = time.perf_counter()
    g = build_scene(cfg.scene, cfg.seed)
    t_build = time.perf_counter() - t0
    cams = camera_path(cfg.capture, cfg.seed)
    for cam in cams:
        save_png(img_dir / cam.name, render_image(g, cam, cfg.capture.background))
    t_render = time.perf_counter() - t0 - t_build
    wanted = {c.name for c in cams}
    stale = sorted(p.name for p in img_dir.glob("*.png") if p.name not in wanted)
    for name in stale:  # a previous, larger capture must not leak images into SfM
        (img_dir / name).unlink()
    if stale:
        log.warning("removed %d stale images from %s: %s", len(stale), img_dir, stale[:5])
    labels = g.extras["label"].numpy().astype(np.int32)
    counts = {name: int((labels == i).sum()) for i, name in LABELS.items()}
    save_cameras(out.path("gt_cameras"), cams, extra={"background": list(cfg.capture.background), "time": 0.0})
    g.save_ply(out.path("gt_gaussians"))
    _save_npy(out.path("gt_labels"), labels)
    _save_npy(out.path("gt_anchors"), g.extras["anchor"].numpy().astype(np.float32))
    write_json(out.path("gt_motion"), {"params": cfg.motion.to_dict(), **motion_tables()})
    summary = {
        "num_gaussians": g.num, "label_counts": counts, "num_images": len(cams),
        "image_size": [cfg.capture.width, cfg.capture.height],
        "seconds": {"build": round(t_build, 3), "render": round(t_render, 3),
                    "total": round(time.perf_counter() - t0, 3)},
        "images": [c.name for c in cams],
    }
    write_json(out.path("gt_scene"), {"config": cfg.to_dict(), **summary})
    return summary
