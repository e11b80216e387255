"""Stage ``render_clip``: render the camera-fixed clip of one view with a round's model.

    anigs render_clip --static static/ [--model round{r-1}/] (--views views/ --view-id ID | --camera-json cam.json) \\
        --out round{r}/ --params '{"num_frames": 25}'

Without ``--model`` (round 0) every frame is the static canonical render. Output: the clip
``round{r}/render/{view}.npz`` (:func:`anigs.video.save_clip`) whose metadata holds the camera,
view id, model path, number of frames and background.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from anigs.animate.render_job import load_animated_scene, render_view

from anigs.animate.config import RenderClipConfig
from anigs import contract
from anigs.stages.static import Outputs as StaticOutputs
from anigs.stages.views import Outputs as ViewsOutputs
from anigs.contract import File
from anigs.stages.update import Outputs as UpdateOutputs
from anigs.cameras import load_camera_json, load_view_camera

log = logging.getLogger("anigs.render_clip")


Config = RenderClipConfig  # the `render_clip` config section


class Outputs(contract.RoundOutputs):
    """A round's folder (``round{r}/``): the rendered clips of its views."""

    LAYOUT = {"clips": File("render/", "the round's rendered clips"),
              "clip": File("render/{view}.npz", "camera-fixed clip float [T,H,W,3] in [0,1] + metadata "
                                                "(camera, view_id, model, num_frames, background)")}

    def clip(self, view: str) -> tuple[np.ndarray, dict]:
        """(frames float32 [T,H,W,3], metadata) of ``view``'s rendered clip."""
        return super().clip("clip", view=view)


@dataclass
class Inputs(contract.Inputs):
    static: StaticOutputs
    out: Path = field(metadata={"help": "the round's folder (the clip goes to render/{view}.npz)"})
    model: UpdateOutputs | None = field(default=None, metadata={"help": "the folder of the model that renders "
                                                                        "(omit for round 0: static)"})
    views: ViewsOutputs | None = None
    view_id: str | None = field(default=None, metadata={"help": "id of the view in --views"})
    camera_json: Path | None = field(default=None, metadata={"help": "one camera JSON instead of --views/--view-id"})


def run(inputs: Inputs, cfg: RenderClipConfig, scene: tuple | None = None) -> Outputs:
    """Render the clip of ``inputs``' camera with its model (none: the static canonical scene);
    ``scene``: the :func:`load_scene` of these inputs, when a caller renders several views."""

    if inputs.camera_json:
        camera = load_camera_json(inputs.camera_json)
    elif inputs.views is not None and inputs.view_id is not None:
        camera = load_view_camera(inputs.views.path("views"), inputs.view_id)
    else:
        raise ValueError("render_clip: give --camera-json FILE, or --views DIR with --view-id ID")
    out = Outputs(inputs.out)
    model = inputs.model.path("model") if inputs.model is not None else None
    canonical = inputs.static.path("canonical")
    scene = scene if scene is not None else load_animated_scene(canonical, cfg, model)
    render_view(scene, camera, out.path("clip", view=inputs.view_id or camera.name), cfg, canonical, model,
                inputs.view_id)
    return out
