"""The sentence that explains each region's decision to a user."""
from __future__ import annotations

from anigs.effects.config import REGION_EFFECTS, DecideConfig
from anigs.effects.geometry import Ground

WHAT = {
    "foliage": "green vegetation standing above the ground (trees, bushes, leaves)",
    "grass": "low green plants on the ground, below the trees and bushes (grass)",
    "flowers": "saturated blossoms of any colour in or next to vegetation",
    "water": "a low, flat, weakly textured surface with a bluish or view-dependent (reflective) colour",
}
MOTION = {
    "foliage": "so the trees and bushes sway (foliage_sway) and their leaves flutter (leaf_flutter)",
    "grass": "so the grass waves (grass_wave)",
    "flowers": "so the flowers bob (flower_bob)",
    "water": "so the water ripples (water_ripple)",
}
REJECTED_NOTE = 0.001  # share of the pixels green but on walls or pictures, from which the foliage reason says so


def reason(region: str, detected: bool, pixel_fraction: float, gaussian_fraction: float, photos_with: int,
           photos: int, cfg: DecideConfig, ground: Ground, rejected_green: float = 0.0) -> str:
    """One or two sentences: what was found (or not), how much, where, and what moves because of it."""
    effects = " and ".join(REGION_EFFECTS[region])
    if detected:
        text = (f"Found {region}: {WHAT[region]} covers {pixel_fraction:.1%} of the photos' pixels "
                f"(in {photos_with} of {photos} photos) and {gaussian_fraction:.1%} of the Gaussians, "
                f"{MOTION[region]}.")
    elif region in ("grass", "water") and ground.plane is None:
        why = ("low vegetation cannot be told from trees without it (all vegetation counts as foliage)"
               if region == "grass" else "water is looked for on it only")
        text = f"No {region} ({effects} skipped): the ground could not be found, and {why}."
    else:
        text = (f"No {region} ({effects} skipped): {WHAT[region]} covers only {pixel_fraction:.2%} of the "
                f"photos' pixels (in {photos_with} of {photos} photos) and {gaussian_fraction:.2%} of the "
                f"Gaussians; at least {cfg.min_pixel_fraction:.1%} and {cfg.min_gaussian_fraction:.1%} are needed.")
    if region == "foliage" and rejected_green >= REJECTED_NOTE:
        text += (f" {rejected_green:.1%} of the pixels are green but lie on flat vertical surfaces or fill a "
                 "rectangle (a wall, a picture, a screen), so they were left still.")
    return text


UNLIFTED_NOTE = 0.1  # share of a region's photo pixels with no region Gaussians in front, from which the reason says so


def unlifted_note(region: str, share: float) -> str:
    """The sentence for a region the photos show but the 3D model mostly lacks (share: of its photo pixels)."""
    return (f" {share:.0%} of the pixels the photos show as {region} have none of the model's {region} in front of "
            "them, so they stay still: parts seen in too few photos to be placed in 3D, or placed where the other "
            "photos see something else such as sky (more photos of them, from nearby, would let them move), "
            f"colours the photos' votes did not take for {region}, or blurred splats reaching mostly past the "
            "plant, or past it in some of the photos that show them (effects.lift.footprint_share, photo_min_share "
            "and photo_vetoes: a sharper fit lets them move).")
