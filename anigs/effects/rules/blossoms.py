"""Rule ``blossoms`` (flowers; last; only when the prompt names plants but no flowers): a flowering
plant's blossoms sway with it.

With ``with_plants`` and a prompt that names foliage but no flowers, the flowers are looked for all the
same as the named plants' blossoms (``Context.blossoms_of``). A candidate the other rules keep and that
the plants hold (at least :data:`~anigs.effects.rules.base.MIN_ATTACHED` of it within the candidate link of their Gaussians) is moved to
their region; the others stay still and are not numbered (the prompt asked for no flowers; a lamp or a
bed on a lawn is none of its business).

Motivation: on the street capture the prompt "a street with
potted plants, shrubs and climbing plants" named no flowers, so the yellow climbing rose's blossoms stayed
still while its leaves swayed (its mark in 12.jpg: 0.27 of it inside the photo's masks).

Test: ``tests/effects/test_blossoms.py``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from anigs.effects.rules.base import MIN_ATTACHED, Candidate, Context, Verdict, fixed
from anigs.typed_config import Section


@dataclass(frozen=True)
class Blossoms(Section):
    """Rule ``blossoms``: the blossoms the named plants hold sway with them; other flowers stay still."""

    WHERE = "effects.rules.blossoms"

    NAME = "blossoms"
    RENAMED = {"min_share": fixed("MIN_ATTACHED", MIN_ATTACHED, "anigs/effects/rules/base.py")}

    #: a prompt that names plants (foliage) but no flowers: the blossoms the flower rules keep and that the named
    #: plants hold (MIN_ATTACHED of them within the link of foliage) sway with them as foliage (a flowering shrub's
    #: blossoms); false: blossoms stay still unless the prompt names flowers
    with_plants: bool = True

    def check(self, cand: Candidate, ctx: Context) -> Verdict | None:
        bearer = ctx.blossoms_of
        if not bearer:
            return None
        share = 0.0
        if ctx.bearer_tree is not None:
            d, _ = ctx.bearer_tree.query(ctx.means[cand.indices], k=1, distance_upper_bound=ctx.link)
            share = float(np.isfinite(d).mean())
        cand.figures["on_plants"] = share
        if share >= MIN_ATTACHED:
            return Verdict(self.NAME, f"blossoms on the {bearer} the prompt names ({share:.0%} of its Gaussians within "
                                      f"{ctx.link:.3g} of a {bearer} Gaussian): they sway with their plant (the prompt "
                                      "names no flowers to bob)", moved_to=bearer)
        return Verdict(self.NAME, f"flowers the prompt does not name, on no {bearer} it names: they stay still")
