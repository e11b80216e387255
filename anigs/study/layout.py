"""The study folder's layout (``anigs study build``; the workflow's ``study`` rule): the study's own
``Outputs``, so its file names are written once, here, like a stage's (:mod:`anigs.contract`).

    Outputs("results/study").path("manifest")   # results/study/manifest.json
"""
from __future__ import annotations

from anigs.contract import File
from anigs.contract import Outputs as _Outputs


class Outputs(_Outputs):
    """The 2AFC study folder (see :mod:`anigs.study.build`)."""

    STAGE = "study"  # not a pipeline stage: `anigs study build`, the workflow's study target
    FOLDER = "study"
    LAYOUT = {
        "page": File("index.html", "the page (the manifest is inlined, so it also works from file://)"),
        "script": File("study.js", "the page logic (order, answers, localStorage, export, posting)"),
        "style": File("study.css", "the page's style"),
        "manifest": File("manifest.json", "the trials, questions and labels, for `anigs study serve` and `tally`"),
        "videos": File("videos/", "each distinct video once, named by content hash (<hash>.mp4)"),
        "readme": File("README.txt", "how to serve the study and tally its answers"),
        "answers": File("answers.jsonl", "the answers `anigs study serve` stores (one JSON line per answer)",
                        optional=True),
    }

    @classmethod
    def public(cls) -> tuple[str, ...]:
        """The URL paths the server shows participants besides the videos: the page and its script
        and style (not the answers, nor the manifest)."""
        return ("/", *(f"/{cls.LAYOUT[k].name}" for k in ("page", "script", "style")))
