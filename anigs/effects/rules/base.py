"""The records the rules share: a numbered 3D :class:`Candidate`, a rule's :class:`Verdict` and the
:class:`Context` every rule of one run reads (the model's Gaussians and what the earlier steps found)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import cv2
import numpy as np
from scipy.spatial import cKDTree

from anigs.effects.kinds import PLANTS, REGIONS

#: a blossom is held by (``held``), or sways with (``blossoms``), the plants when this share of its Gaussians lies
#: within the candidate link of theirs (the two rules' ``min_share`` knobs until 0.13, the one ``min_attached``
#: before: at 0.15 and 0.45 they moved no figure of the labelled benchmark or the decoys)
MIN_ATTACHED = 0.3


def fixed(name: str, value: float, module: str) -> str:
    """What a config error says of a knob that is a constant now (issue 49: it moved no figure)."""
    return (f"the constant {name} = {value:g} of {module} (at half and 1.5 times its value it moved no figure of "
            "the labelled benchmark or the decoys: benchmarks/knob_sensitivity.py, CHANGELOG.md)")


@dataclass
class Candidate:
    """One 3D candidate region: ``indices`` of its Gaussians and the verdict (kept, or the rule that set it
    aside or moved it, with the reason); ``figures``: what the rules measured on it."""

    number: int
    region: str
    indices: np.ndarray
    centre: np.ndarray
    extent: float
    kept: bool = True
    rule: str = ""
    reason: str = ""
    moved_to: str = ""
    figures: dict = field(default_factory=dict)

    @property
    def open(self) -> bool:
        """No rule has decided it yet: it is kept in its own region."""
        return self.kept and not self.moved_to

    def apply(self, verdict: "Verdict") -> None:
        """Take a rule's verdict: moved to another region, or still."""
        self.rule, self.reason = verdict.rule, verdict.reason
        if verdict.moved_to:
            self.moved_to = verdict.moved_to
        else:
            self.kept = False

    def to_json(self) -> dict:
        return {"number": self.number, "region": self.region, "num_gaussians": int(len(self.indices)),
                "centre": [round(float(x), 4) for x in self.centre], "extent": round(float(self.extent), 4),
                "kept": bool(self.kept), "rule": self.rule, "reason": self.reason, "moved_to": self.moved_to,
                "figures": {k: round(float(v), 4) for k, v in self.figures.items()}}


@dataclass(frozen=True)
class Verdict:
    """A rule's decision on a candidate: still (``moved_to`` empty) or moved to region ``moved_to``."""

    rule: str
    reason: str
    moved_to: str = ""


@dataclass(frozen=True)
class Bands:
    """The colour bands of the photo regions (``effects.regions``) that the rules read on the Gaussians' own colours."""

    green_hue: tuple[float, float]
    green_min_saturation: float
    flower_green_hue: tuple[float, float]
    white_flowers: bool


class Rule(Protocol):
    """A rule of the table: its knobs are its fields; ``check`` records its figures on the candidate and
    returns its verdict, or None (the candidate goes on to the next rule)."""

    NAME: str

    def check(self, cand: Candidate, ctx: "Context") -> Verdict | None: ...


def hue(rgb: np.ndarray) -> np.ndarray:
    """Hue [M] in degrees of colours [M,3]."""
    return cv2.cvtColor(np.clip(rgb, 0, 1).astype(np.float32)[None], cv2.COLOR_RGB2HSV)[0, :, 0]


def saturation(rgb: np.ndarray) -> np.ndarray:
    """(max - min) / max [M] of colours [M,3]."""
    mx, mn = rgb.max(1), rgb.min(1)
    return (mx - mn) / np.maximum(mx, 1e-6)


def green(colours: np.ndarray, bands: Bands) -> np.ndarray:
    """bool [N]: Gaussians whose own colour is vegetation green (stems, leaves)."""
    h = hue(colours)
    sat = saturation(colours)
    return (h >= bands.green_hue[0]) & (h <= bands.green_hue[1]) & (sat >= bands.green_min_saturation) & \
        (colours[:, 1] >= colours[:, 0])


@dataclass
class Context:
    """What every rule of one run reads: the Gaussians (``means`` [N,3], own ``colours`` [N,3] in [0,1]),
    their lifted ``region_of`` [N], ``height`` above the ground plane [N] (None: no plane) and the cameras'
    ``cam_height``, the neighbourhood ``radius`` and candidate ``link`` (world units), ``above_cameras``
    bool [N] (None: not checked), ``blossoms_of`` (rule ``blossoms``: the region whose plants' blossoms
    the flowers are; None: flowers are their own region), the ``unasked`` regions, the colour ``bands``, the RANSAC ``seed`` and
    each Gaussian's unit ``flattest`` axis [N,3] (its splat's normal; None: not known).
    The neighbour trees are built once, with the context (the bearers' again by :meth:`bear`)."""

    means: np.ndarray
    colours: np.ndarray
    region_of: np.ndarray
    height: np.ndarray | None
    cam_height: float
    radius: float
    link: float
    bands: Bands
    above_cameras: np.ndarray | None = None
    blossoms_of: str | None = None
    #: regions looked for only so that the rules move their parts elsewhere (the flowers, as the named plants'
    #: blossoms): what stays in them is still and not numbered
    unasked: tuple[str, ...] = ()
    seed: int = 0
    flattest: np.ndarray | None = None  # [N,3] each Gaussian's unit flattest axis (None: not known)

    def __post_init__(self) -> None:
        self.is_plant = np.isin(self.region_of, [REGIONS.index(r) for r in PLANTS])
        self.tree_all = cKDTree(self.means)
        self.holders = np.flatnonzero(np.isin(self.region_of, [REGIONS.index("foliage"), REGIONS.index("grass")])
                                      | green(self.colours, self.bands))
        self.holder_tree = cKDTree(self.means[self.holders]) if len(self.holders) else None
        self.bear(self.region_of)

    def bear(self, region_of: np.ndarray) -> None:
        """The blossoms' bearers: the Gaussians of ``blossoms_of`` in ``region_of`` [N]. :func:`run_table` calls it
        again once that region's candidates are decided, so blossoms attach only to plants that survived every rule."""
        self.bearers = (np.flatnonzero(region_of == REGIONS.index(self.blossoms_of)) if self.blossoms_of
                        else np.zeros(0, np.int64))
        self.bearer_tree = cKDTree(self.means[self.bearers]) if len(self.bearers) else None

