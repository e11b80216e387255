"""Rule ``own_colour`` (flowers): a blossom carries a blossom's own colour in 3D; verdicts ``light``,
``leaf_glare`` and ``not_blossom_colour``.

The candidate's Gaussians carry their own (view-independent) colour. At least ``min_share`` of a blossom's
are saturated and bright (saturation >= ``min_saturation``, value >= ``min_value``, hue outside the
flower-green band of ``effects.regions``; a bed's stems and leaves make up the rest) or, with
``effects.regions.white_flowers``, at least ``MIN_WHITE_SHARE`` are white (saturation under
``WHITE_MAX_SATURATION``, every channel >= ``WHITE_MIN_VALUE``, not greenish: a green hue at saturation
>= ``greenish_min_saturation``). Then, in this order:

- ``light``: whiter than coloured and at least ``LIGHT_MIN_ABOVE`` of it above every camera (along the
  world's up): a light under a ceiling or a bright sky gap;
- ``leaf_glare``: white but with at least as many pale, bright greenish Gaussians (saturation under
  ``glare_max_saturation``, every channel >= ``glare_min_value``) as white ones and no blossom colour:
  sunlit glare on a frond whitens toward its centre, while white petals are mostly white;
- ``not_blossom_colour``: neither coloured nor white enough: glare on leaves, bark, soil or a blend.

Motivation: on the real fern capture (``benchmarks/real/labels/fern-llff.json``) "flowers" in the prompt
chose flower_bob for warm-white ceiling lamps (81% white, all above the cameras) and two patches of glare
on the fronds (16% and 24% white-ish, the rest pale green; one of 64 Gaussians 42% white, 50% glare).

Test: ``tests/effects/test_colour_rule.py``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from anigs.effects.rules.base import Candidate, Context, Verdict, fixed, hue, saturation
from anigs.typed_config import Section

MIN_WHITE_SHARE = 0.35  # a flower candidate is white petals when this share of its Gaussians are white (or more)
WHITE_MAX_SATURATION = 0.15  # a white Gaussian: saturation under this ...
WHITE_MIN_VALUE = 0.8  # ... and every channel at least this (not greenish)
LIGHT_MIN_ABOVE = 0.5  # a white candidate with this share of its Gaussians above every camera is a light
HERE = "anigs/effects/rules/own_colour.py"


@dataclass(frozen=True)
class OwnColour(Section):
    """Rule ``own_colour``: flowers need a blossom's own colour (coloured or white petals)."""

    WHERE = "effects.rules.own_colour"

    NAME = "own_colour"
    RENAMED = {"min_white_share": fixed("MIN_WHITE_SHARE", MIN_WHITE_SHARE, HERE),
               "white_max_saturation": fixed("WHITE_MAX_SATURATION", WHITE_MAX_SATURATION, HERE),
               "white_min_value": fixed("WHITE_MIN_VALUE", WHITE_MIN_VALUE, HERE),
               "light_min_above": fixed("LIGHT_MIN_ABOVE", LIGHT_MIN_ABOVE, HERE)}

    #: a flower candidate: this share of its Gaussians' own colours (or more) are a blossom's ...
    min_share: float = 0.15
    min_saturation: float = 0.3      # ... at least this saturation ...
    min_value: float = 0.45          # ... and this brightest channel (bark and soil are darker)
    greenish_min_saturation: float = 0.06  # a green hue at this saturation or more is greenish (not white)
    glare_max_saturation: float = 0.3  # glare: greenish, saturation under this ...
    glare_min_value: float = 0.6     # ... and every channel at least this

    def check(self, cand: Candidate, ctx: Context) -> Verdict | None:
        rgb = ctx.colours[cand.indices]
        mx, mn = rgb.max(1), rgb.min(1)
        sat = saturation(rgb)
        h = hue(rgb)
        lo, hi = ctx.bands.flower_green_hue
        coloured = (sat >= self.min_saturation) & (mx >= self.min_value) & ~((h >= lo) & (h <= hi))
        greenish = (h >= ctx.bands.green_hue[0]) & (h <= ctx.bands.green_hue[1]) & (sat >= self.greenish_min_saturation)
        white = ((sat < WHITE_MAX_SATURATION) & (mn >= WHITE_MIN_VALUE) & ~greenish
                 if ctx.bands.white_flowers else np.zeros(len(rgb), bool))
        glare = greenish & (sat < self.glare_max_saturation) & (mn >= self.glare_min_value)
        c_share, w_share, g_share = float(coloured.mean()), float(white.mean()), float(glare.mean())
        cand.figures.update(own_coloured=c_share, own_white=w_share, own_glare=g_share)
        if w_share > c_share and ctx.above_cameras is not None:
            high = float(ctx.above_cameras[cand.indices].mean())
            cand.figures["above_cameras"] = high
            if high >= LIGHT_MIN_ABOVE:
                return Verdict("light", f"white and above every camera ({high:.0%} of its Gaussians): a light under "
                                        "a ceiling or a bright gap, not blossoms")
        if c_share < self.min_share and w_share >= MIN_WHITE_SHARE and g_share >= w_share:
            return Verdict("leaf_glare", f"white ({w_share:.0%}) but as often or more pale green ({g_share:.0%}), with "
                                         f"no blossom colour ({c_share:.0%}): sunlit glare on leaves, which whitens "
                                         "toward its centre, not white petals")
        if c_share < self.min_share and w_share < MIN_WHITE_SHARE:
            return Verdict("not_blossom_colour",
                           f"too few of its Gaussians have a blossom's own colour ({c_share:.0%} saturated and bright "
                           f"off the green band, {w_share:.0%} white; median saturation {float(np.median(sat)):.2f}, "
                           f"value {float(np.median(mx)):.2f}): glare on leaves, bark, soil or a blend of them")
        return None
