"""Embedded synthetic demo scene: procedural garden Gaussians with labels, GT wind motion, capture."""
from anigs.synth.capture import CameraPathConfig, SynthConfig, camera_path, render_image, write_capture
from anigs.synth.motion import (ALL_EFFECT_TYPES, EFFECT_TYPES, LABEL_EFFECTS, EffectParams, MotionParams, gt_clip_offsets,
                                gt_offsets, motion_class, motion_tables)
from anigs.synth.build import build_scene
from anigs.synth.scene import ALL_LABELS, LABEL_IDS, LABELS, WATER_LABEL, SceneConfig

__all__ = [
    "CameraPathConfig", "SynthConfig", "camera_path", "render_image", "write_capture",
    "ALL_EFFECT_TYPES", "EFFECT_TYPES", "LABEL_EFFECTS", "EffectParams", "MotionParams", "gt_clip_offsets", "gt_offsets",
    "motion_class", "motion_tables", "ALL_LABELS", "LABEL_IDS", "LABELS", "WATER_LABEL",
    "SceneConfig", "build_scene",
]
