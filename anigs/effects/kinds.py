"""Regions and the effects each region carries.

A *region* is what the detector finds (foliage, grass, flowers, water); an *effect* is what the
animation simulates. Foliage carries two effects (``foliage_sway``, ``leaf_flutter``) that share
its masks and Gaussians.
"""
from __future__ import annotations

REGIONS: tuple[str, ...] = ("foliage", "grass", "flowers", "water")
REGION_EFFECTS: dict[str, tuple[str, ...]] = {
    "foliage": ("foliage_sway", "leaf_flutter"),
    "grass": ("grass_wave",),
    "flowers": ("flower_bob",),
    "water": ("water_ripple",),
}
EFFECT_REGION: dict[str, str] = {e: r for r, effs in REGION_EFFECTS.items() for e in effs}
EFFECTS: tuple[str, ...] = tuple(EFFECT_REGION)
PLANTS: tuple[str, ...] = ("foliage", "grass", "flowers")
