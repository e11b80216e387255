"""Stage ``export``: the animated scene for other tools.

    anigs export --static static/ --model round4/ --out export/ --params '{...export section...}'

``scene.anigs`` (the compact format of :mod:`anigs.viewer.compact`: the canonical Gaussians once,
DCT motion coefficients of the moving ones only; ``load_compact(path).frame(t)`` reproduces the
library's frame t exactly), ``animated.ply`` (the standard 3DGS PLY plus per-Gaussian DCT
properties) with its JSON sidecar, the static scene (``static/canonical.ply``) as glTF binary with
``KHR_gaussian_splatting`` (``canonical.glb``, its node turned +y up) and as SPZ (``canonical.spz``),
and with ``frames: true`` the per-frame PLY sequence.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

from anigs import contract
from anigs.stages.static import Outputs as StaticOutputs
from anigs.contract import File
from anigs.stages.update import Outputs as UpdateOutputs
from anigs import __version__
from anigs.export import save_animated_ply, sidecar
from anigs.export.config import ExportConfig
from anigs.formats.gltf import save_glb
from anigs.formats.spz import save_spz
from anigs.io import write_json
from anigs.viewer.compact import save_compact, write_frame_plys

log = logging.getLogger("anigs.export")


class Outputs(contract.Outputs):
    """The export folder of a variant (``export/``)."""

    LAYOUT = {"compact": File("scene.anigs", "compact animated scene (anigs.viewer.compact): canonical once, "
                                            "DCT motion of the moving Gaussians"),
              "ply": File("animated.ply", "standard 3DGS PLY + per-Gaussian DCT properties"),
              "sidecar": File("animated.json", "the PLY's sidecar: K, T, fps, dynamic count, frames, compact"),
              "glb": File("canonical.glb", "the static scene as glTF binary with KHR_gaussian_splatting "
                                           "(positions as canonical.ply's, the node stands it +y up)"),
              "spz": File("canonical.spz", "the static scene as SPZ v3 (anigs's +z-up frame, as canonical.ply)"),
              "frames": File("frames/", "with export.frames: one 3DGS PLY per frame", optional=True)}


@dataclass
class Inputs(contract.Inputs):
    static: StaticOutputs
    model: UpdateOutputs = field(metadata={"help": "the update stage's folder of the model"})
    out: Path = field(metadata={"help": "the export folder"})


Config = ExportConfig  # the `export` config section


def run(inputs: Inputs, cfg: ExportConfig) -> Outputs:
    """Export the model into the export folder (``animated.json`` holds what was written)."""

    canonical, deformation, _ = inputs.model.load(inputs.static.path("canonical"))
    out = Outputs(inputs.out)
    names = write_frame_plys(out.root, canonical, deformation, cfg.frame_step) if cfg.frames else []
    save_compact(out.path("compact"), canonical, deformation, cfg.fps)
    extra = save_animated_ply(out.path("ply"), canonical, deformation)
    meta = sidecar(deformation, cfg.fps, Outputs.LAYOUT["ply"].name, extra)
    meta["frames"] = names
    meta["compact"] = Outputs.LAYOUT["compact"].name
    static = inputs.static.canonical()
    save_glb(out.path("glb"), static, generator=f"anigs {__version__}")
    save_spz(out.path("spz"), static)
    meta["static"] = {"glb": Outputs.LAYOUT["glb"].name, "spz": Outputs.LAYOUT["spz"].name,
                      "up": "+z (anigs's frame; canonical.glb's node turns it +y up)"}
    write_json(out.path("sidecar"), meta)
    log.info("export: %d frame PLYs and %s (%d dynamic of %d Gaussians, K=%d, T=%d) -> %s",
             len(names), out.path("ply").name, deformation.num_dynamic, canonical.num, deformation.num_bases, deformation.num_frames, out.root)
    return out
