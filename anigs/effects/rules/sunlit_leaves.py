"""Rule ``sunlit_leaves`` (flowers; first): a yellow-green candidate high in a crown is foliage in the sun.

A flower candidate whose median own hue lies within ``hue_margin`` degrees below the vegetation band and
of which at least ``MIN_IN_CROWN`` lies above ``crown_min_height`` x the camera height is sunlit leaves,
not blossoms (flower heads stay lower): moved to foliage, so it sways instead of bobbing. It runs first;
the other flower rules apply to the candidates it leaves.

Motivation: the facade decoy's tree with yellow
sunlit leaves (``anigs.synth.decoys``), whose crown the colour cues took for blossoms.

Test: ``tests/effects/test_decoys.py`` (the facade decoy: no flower_bob, its leaves sway).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from anigs.effects.rules.base import Candidate, Context, Verdict, fixed, hue
from anigs.typed_config import Section

MIN_IN_CROWN = 0.5  # sunlit leaves: at least this share of the candidate high in a crown


@dataclass(frozen=True)
class SunlitLeaves(Section):
    """Rule ``sunlit_leaves``: yellow-green flowers high in a crown move to foliage."""

    WHERE = "effects.rules.sunlit_leaves"

    NAME = "sunlit_leaves"
    RENAMED = {"min_in_crown": fixed("MIN_IN_CROWN", MIN_IN_CROWN, "anigs/effects/rules/sunlit_leaves.py")}

    #: flowers: a median hue this many degrees below the green band, high in a crown, is sunlit leaves (foliage)
    hue_margin: float = 20.0
    #: ... high in a crown: above this x camera height (flower heads stay lower) ...
    crown_min_height: float = 0.4

    def check(self, cand: Candidate, ctx: Context) -> Verdict | None:
        h = float(np.median(hue(ctx.colours[cand.indices])))
        cand.figures["hue"] = h
        lo = ctx.bands.green_hue[0]
        if ctx.height is None or not (lo - self.hue_margin <= h < lo):
            return None
        high = float((ctx.height[cand.indices] >= self.crown_min_height * ctx.cam_height).mean())
        cand.figures["in_crown"] = high
        if high < MIN_IN_CROWN:
            return None
        return Verdict(self.NAME, f"yellow-green (hue {h:.0f} deg) and high in a crown ({high:.0%} above "
                                  f"{self.crown_min_height:g} x the camera height): "
                                  "sunlit leaves, so they sway with the foliage instead of bobbing as flowers",
                       moved_to="foliage")
