"""Rule ``held`` (flowers; verdict ``not_held``): a blossom grows on a plant.

Fewer than :data:`~anigs.effects.rules.base.MIN_ATTACHED` of the candidate's Gaussians have a foliage or grass Gaussian, or a Gaussian of
vegetation-green own colour (a stem), within the candidate link (a green Gaussian holds itself): a lamp,
a window surround or paint seen next to leaves.

Motivation: the facade decoy's red brick window
surrounds and the room decoy's lamps beside its potted plant (``anigs.synth.decoys``).

Test: ``tests/effects/test_decoys.py``, ``tests/effects/test_colour_rule.py`` (blossoms held by stems are kept).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from anigs.effects.rules.base import MIN_ATTACHED, Candidate, Context, Verdict, fixed
from anigs.typed_config import Section


@dataclass(frozen=True)
class Held(Section):
    """Rule ``held``: flowers no plant holds are still."""

    WHERE = "effects.rules.held"

    NAME = "held"
    RENAMED = {"min_share": fixed("MIN_ATTACHED", MIN_ATTACHED, "anigs/effects/rules/base.py")}

    def check(self, cand: Candidate, ctx: Context) -> Verdict | None:
        if ctx.holder_tree is None:
            share = 0.0
        else:
            d, _ = ctx.holder_tree.query(ctx.means[cand.indices], k=2, distance_upper_bound=ctx.link)
            # a Gaussian holds itself when it is green (a stem): count another holder or a green self
            own = np.isin(cand.indices, ctx.holders)
            share = float((np.isfinite(d[:, 1]) | (np.isfinite(d[:, 0]) & ~own)).mean())
        cand.figures["held"] = share
        if share >= MIN_ATTACHED:
            return None
        return Verdict("not_held", f"is not held by a plant (only {share:.0%} of its Gaussians lie within {ctx.link:.3g} "
                                   "of leaves or stems): a blossom grows on a plant, this is a lamp, a window surround "
                                   "or paint seen next to one")
