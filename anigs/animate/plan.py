"""The dataset-model loop unrolled into rounds (pure functions; the Snakefile calls them).

Round r (1-based) adds ``views_per_round`` views of the queue (paper: one view per dataset
update, location by location, yaw 0 -> +90 -> -90), renders every view in its dataset with
the model of round r-1 (round 0 = the static canonical model), refines each view, and trains
the model on all targets of round r. Ablations change only which files feed which job:

* ``view_expansion: false``  -- every view is in the dataset from round 1;
* ``dataset_update: false``  -- each view's target is generated once, from the static model,
  in the first round that contains the view, and reused afterwards.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class RoundPlan:
    """How many rounds a variant runs and which views each round holds."""

    num_views: int
    views_per_round: int = 1
    extra_rounds: int = 0
    view_expansion: bool = True
    dataset_update: bool = True

    def __post_init__(self) -> None:
        if self.num_views < 1:
            raise ValueError(f"the view queue must hold at least one view, got {self.num_views}")
        if self.views_per_round < 1:
            raise ValueError(f"views_per_round must be >= 1, got {self.views_per_round}")
        if self.extra_rounds < 0:
            raise ValueError(f"extra_rounds must be >= 0, got {self.extra_rounds}")

    @property
    def num_rounds(self) -> int:
        """Rounds until full coverage, plus refresh rounds (the same for every ablation)."""
        return math.ceil(self.num_views / self.views_per_round) + self.extra_rounds

    def view_ids(self) -> list[str]:
        return [view_id(i) for i in range(self.num_views)]

    def dataset(self, r: int) -> list[str]:
        """View ids in the dataset of round r."""
        self._check_round(r)
        n = self.num_views if not self.view_expansion else min(r * self.views_per_round, self.num_views)
        return self.view_ids()[:n]

    def first_round(self, view: str) -> int:
        """The first round whose dataset contains ``view``."""
        for r in range(1, self.num_rounds + 1):
            if view in self.dataset(r):
                return r
        raise KeyError(f"view {view!r} is not in the queue of {self.num_views} views")

    def target_round(self, r: int, view: str) -> int:
        """Round whose target file of ``view`` trains round r."""
        return r if self.dataset_update else self.first_round(view)

    def render_model_round(self, r: int) -> int:
        """Model round used to render the clips of round r (0 = static canonical)."""
        self._check_round(r)
        return r - 1 if self.dataset_update else 0

    def _check_round(self, r: int) -> None:
        if not 1 <= r <= self.num_rounds:
            raise ValueError(f"round {r} outside 1..{self.num_rounds}")


def view_id(i: int) -> str:
    """Queue position -> view id (``v00``, ``v01``, ...)."""
    return f"v{i:02d}"


