"""Effects the scene calls for: which of foliage, grass, flowers and water a scene contains, and where.

``detect_effects(images, cameras, gaussians, cfg) -> EffectsResult`` analyses capture photos with
the fitted static model (colour indices, height above the fitted ground, planarity, texture,
multi-view consistency; no downloaded weights; optionally a semantic segmenter with local
weights, :mod:`anigs.effects.segmenter`). ``EffectsResult.to_json()`` is the
``effects.json`` object, ``save_overview`` writes the overview PNG.
"""
from anigs.effects.config import EFFECT_REGION, EFFECTS, REGION_EFFECTS, REGIONS, EffectsConfig
from anigs.effects.detect import EffectResult, EffectsResult, detect_effects
from anigs.effects.overview import save_overview

__all__ = ["EffectsConfig", "EFFECTS", "EFFECT_REGION", "REGIONS", "REGION_EFFECTS", "EffectResult", "EffectsResult",
           "detect_effects", "save_overview"]
