"""Stage ``animate``: the dataset-model loop of the paper unrolled into rounds.

It has a config section and a Snakemake target (``snakemake animate``) but no command of its
own: its jobs are the ``render_clip``, ``refine`` and ``update`` stages of every round, in the
order :class:`anigs.animate.plan.RoundPlan` gives.
"""
from __future__ import annotations

from anigs.animate.plan import RoundPlan

from anigs.animate.config import AnimateConfig

Config = AnimateConfig  # the `animate` config section

__all__ = ["Config", "RoundPlan"]
