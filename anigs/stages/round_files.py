"""Which files the jobs of one (scene, variant)'s animation rounds read (the rules' input functions
ask here): the round plan (:class:`anigs.animate.plan.RoundPlan`) applied to the round folders of
the update stage, with a round's render and refine work done by one job per view or one per round."""
from __future__ import annotations

from dataclasses import dataclass

from anigs.animate.plan import RoundPlan
from anigs.stages.targets import stage_outputs


def round_folder(results: str, scene: str, variant: str, r: int | str) -> str:
    """Round r's folder without the round plan: a rule whose job reads no views checkpoint (refine)
    can name it (the plan needs the queue's length, which a remote job cannot ask for)."""
    return stage_outputs("update").under(results, scene=scene, variant=variant, round=r)


@dataclass(frozen=True)
class RoundFiles:
    """The round files of ``scene``/``variant`` under the results root ``results``; ``per_round``:
    one job renders and refines a round's views and writes their folders (``round_jobs: round``)."""

    plan: RoundPlan
    results: str
    scene: str
    variant: str
    per_round: bool

    def folder(self, r: int | str) -> str:
        """Round r's folder (the render_clip, refine and update stages write into it)."""
        return round_folder(self.results, self.scene, self.variant, r)

    def model(self, r: int | str) -> str:
        """The model file round r's update writes."""
        return stage_outputs("update").under(self.results, "model", scene=self.scene, variant=self.variant, round=r)

    def final_model(self) -> str:
        """The last round's model (what the final stages use when the scene moves)."""
        return self.model(self.plan.num_rounds)

    def render_model(self, r: int) -> list[str]:
        """The model that renders round r's clips; none when the static canonical model does (round 0)."""
        m = self.plan.render_model_round(r)
        return [self.model(m)] if m > 0 else []

    def init_model(self, r: int) -> list[str]:
        """The model round r's update starts from (round r-1's); none in round 1."""
        return [self.model(r - 1)] if r > 1 else []

    def clip_views(self, r: int) -> list[str]:
        """Views whose clip round r renders and refines (those whose target trains round r that no
        earlier round made)."""
        return [v for v in self.plan.dataset(r) if self.plan.target_round(r, v) == r]

    def _refine(self, r: int, key: str, **fields: str) -> str:
        return str(stage_outputs("refine")(self.folder(r)).path(key, **fields))

    def target_files(self, r: int) -> list[str]:
        """The target clip of each view of round r's dataset, in the round that made it."""
        return [self._refine(self.plan.target_round(r, v), "target", view=v) for v in self.plan.dataset(r)]

    def targets(self, r: int) -> list[str]:
        """Round r's update inputs: the per-view jobs' target files, or the round jobs' target folders."""
        if not self.per_round:
            return self.target_files(r)
        return sorted({self._refine(self.plan.target_round(r, v), "targets") for v in self.plan.dataset(r)})

    def earlier_targets(self, r: int) -> list[str]:
        """Round jobs: the target folders of earlier rounds that round r trains on (its own folder is
        the job's output); none with per-view jobs (the update job's inputs)."""
        if not self.per_round:
            return []
        own = self._refine(r, "targets")
        return [t for t in self.targets(r) if t != own]
