"""The pipeline's stages, one module each (``anigs/stages/<name>.py``: ``Config``, ``Outputs``,
``Inputs``, ``run(inputs, cfg)``). The list of stages is :data:`anigs.registry.STAGES`, re-exported here."""
from anigs.registry import BY_NAME, RENAMED, STAGES, Scope, Stage, get, sections, sections_of

__all__ = ["BY_NAME", "RENAMED", "STAGES", "Scope", "Stage", "get", "sections", "sections_of"]
