"""Stage ``static``: fit the static canonical 3DGS from posed images and SfM points.

    anigs static --images DIR --cameras sfm/cameras.json --points sfm/points.npz \
                 [--tracks sfm/tracks.npz] --out results/demo/static [--params JSON]
    anigs static ... --splat PATH --report sfm/report.json   # a splat trained elsewhere: no fit
    anigs static --images DIR --cameras sfm/cameras.json --points sfm/points.npz --plan-only [--params JSON]

Writes ``OUT/canonical.ply`` (standard 3DGS layout) and ``OUT/metrics.json``. While it runs,
``OUT/checkpoint.ply`` holds the last good state; it is removed on success and kept when the
fit diverges. With ``--splat`` the fit is skipped: the splat is read in its trainer's frame, brought
into the sfm folder's and measured against the photos (:mod:`anigs.static.imported`); one that does
not render them stops the stage with the frames it tried. With ``--plan-only`` it prints the fit's plan
(:func:`anigs.static.fit.plan_static`: steps, Gaussians, photo size, estimated minutes) and stops.
"""
from __future__ import annotations

import argparse
import json
import logging
from dataclasses import dataclass, field
from pathlib import Path

from anigs import contract
from anigs.stages.command import add_params, parse_params
from anigs.contract import File
from anigs.stages.sfm import Outputs as SfmOutputs
from anigs.gaussians import load_ply
from anigs.images import load_inputs
from anigs.io import write_json
from anigs.sfm.model import load_points
from anigs.sfm.tracks import load_tracks
from anigs.static.fit import StaticConfig, StaticPlan, fit_static, plan_static
from anigs.static.report import draw_fit, held_out_text

Config = StaticConfig  # the `static` config section

log = logging.getLogger("anigs.static")


class Outputs(contract.Outputs):
    """The static stage's folder: the canonical 3DGS."""

    LAYOUT = {
        "canonical": File("canonical.ply", "the canonical 3DGS, standard 3DGS PLY layout (any 3DGS viewer opens it)"),
        "metrics": File("metrics.json", "held-out and train PSNR/SSIM, Gaussian count, seconds, the plan (budget, "
                                        "steps, estimated time), accuracy (the next level's cost, a too-blurry warning), "
                                        "inputs, config"),
        "fit": File("fit.png", "held-out PSNR against the steps, the next level and its cost in CPU minutes, "
                               "the too-blurry warning (this machine's minutes: metrics.json)"),
        "checkpoint": File("checkpoint.ply", "the last good state while the fit runs; removed on success, "
                                             "kept when the fit diverges", optional=True),
    }

    def canonical(self):
        """The canonical :class:`~anigs.gaussians.Gaussians`."""

        p = self.path("canonical")
        if not p.is_file():
            raise FileNotFoundError(f"{p}: missing (run the {self.STAGE} stage)")
        return load_ply(p)

    def metrics(self) -> dict:
        """``metrics.json``."""
        return self.json("metrics")

    def fit_warning(self) -> str | None:
        """The fit's own verdict on its sharpness: the too-blurry warning with the cheapest change that helps
        (``accuracy.warning`` of ``metrics.json``); None when it gave none or there are no metrics."""
        if not self.exists("metrics"):
            return None
        return self.metrics().get("accuracy", {}).get("warning")

@dataclass
class Inputs(contract.Inputs):
    """What the static stage reads: the sfm stage's posed images and points."""

    images: Path = contract.upstream(SfmOutputs, "images", "folder of the input images")
    cameras: Path = contract.upstream(SfmOutputs, "cameras", "cameras (anigs convention), one entry per used image")
    points: Path = contract.upstream(SfmOutputs, "points", "the SfM points: xyz [P,3] and rgb [P,3]")
    out: Outputs = contract.output_folder(Outputs)
    tracks: Path | None = contract.upstream(SfmOutputs, "tracks", "the SfM points each photo observes, for the "
                                            "depth loss (static.depth_weight); without it: no depth loss",
                                            default=None)
    no_progress: bool = field(default=False, metadata={"help": "hide the progress bar"})
    splat: Path | None = field(default=None, metadata={
        "help": "a splat trained elsewhere (PLY, compressed PLY, SPZ, glb, .splat): imported instead of fitted"})
    report: Path | None = contract.upstream(SfmOutputs, "report", "the sfm stage's report: its frame (the COLMAP "
                                            "project's normalisation) for an imported splat", default=None)


def run(inputs: Inputs, cfg: StaticConfig) -> Outputs:
    """Fit the canonical 3DGS to the sfm stage's posed images from its points (planned first, :func:`plan`);
    writes the canonical PLY and the metrics (a checkpoint while it runs, kept when the fit diverges)."""
    out, images, cameras, points = inputs.out, inputs.images, inputs.cameras, inputs.points
    imgs, cams = load_inputs(images, cameras, compact=True)  # uint8: a quarter of the memory
    pts, cols = load_points(points)
    if inputs.splat is not None:
        return _import(inputs, cfg, imgs, cams, pts)
    fit_plan = plan_static(imgs, cams, pts, cols, cfg)
    tracks = load_tracks(inputs.tracks) if inputs.tracks is not None else None
    out.root.mkdir(parents=True, exist_ok=True)
    ckpt = out.path("checkpoint")
    gaussians, metrics = fit_static(imgs, cams, pts, cols, cfg, progress=not inputs.no_progress,
                                    checkpoint_path=ckpt, tracks=tracks, plan=fit_plan)
    ply = out.path("canonical")
    gaussians.save_ply(ply)
    back = load_ply(ply)  # the artifact must round-trip
    if back.num != gaussians.num:
        raise RuntimeError(f"{ply}: wrote {gaussians.num} Gaussians but read back {back.num}")
    metrics["inputs"] = {"images": str(images), "cameras": str(cameras), "points": str(points),
                         "num_points": int(len(pts))}
    if inputs.tracks is not None:
        metrics["inputs"]["tracks"] = str(inputs.tracks)
    metrics["config"] = _config_dict(cfg)
    write_json(out.path("metrics"), metrics)
    draw_fit(metrics, out.path("fit"))
    if ckpt.exists():
        ckpt.unlink()
    log.info("static fit: %d Gaussians -> %s", metrics["num_gaussians"], ply)
    return out


def plan(inputs: Inputs, cfg: StaticConfig) -> StaticPlan:
    """The plan of the fit :func:`run` would make (nothing is fitted or written)."""
    imgs, cams = load_inputs(inputs.images, inputs.cameras, compact=True)
    pts, cols = load_points(inputs.points)
    return plan_static(imgs, cams, pts, cols, cfg)


def _import(inputs: Inputs, cfg: StaticConfig, imgs, cams, pts) -> Outputs:
    """The static folder of a splat trained elsewhere (no fit): canonical.ply in the sfm folder's frame,
    metrics.json with its PSNR against the photos and where its frame came from, fit.png photo | render."""
    from anigs.static.imported import draw_import, import_splat, sfm_frame

    out = inputs.out
    colmap_to_sfm = sfm_frame(inputs.report)
    g, metrics = import_splat(inputs.splat, [im.numpy() for im in imgs], cams, pts, colmap_to_sfm, cfg.imported,
                              cfg.holdout_every)
    out.root.mkdir(parents=True, exist_ok=True)
    g.save_ply(out.path("canonical"))
    metrics["inputs"] = {"images": str(inputs.images), "cameras": str(inputs.cameras), "points": str(inputs.points),
                         "splat": str(inputs.splat), "report": str(inputs.report) if inputs.report else None}
    metrics["config"] = _config_dict(cfg)
    write_json(out.path("metrics"), metrics)
    draw_import(g, [im.numpy() for im in imgs], cams, metrics, out.path("fit"))
    log.info("static: imported %d Gaussians -> %s", g.num, out.path("canonical"))
    return out


def _config_dict(cfg) -> dict:
    import dataclasses

    d = dataclasses.asdict(cfg)
    d["background"] = cfg.background if isinstance(cfg.background, str) else list(cfg.background)
    return d


# ---- command line: anigs static ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    Inputs.add_arguments(p, optional=("out",))
    add_params(p, "static")
    p.add_argument("--plan-only", action="store_true", help="print the fit's plan (steps, Gaussians, photo size, "
                   "estimated minutes on this machine) and stop: nothing is fitted or written (no --out needed)")


def main(args: argparse.Namespace) -> int:
    inputs, cfg = Inputs.from_args(args), StaticConfig.from_dict(parse_params(args.params))
    if getattr(args, "plan_only", False):  # (a Namespace built by hand may not have it)
        if inputs.splat is not None:
            raise ValueError("anigs static: --plan-only plans a fit; with --splat nothing is fitted")
        fit_plan = plan(inputs, cfg)
        print(fit_plan.text())
        print(json.dumps(fit_plan.as_dict(), indent=1))
        return 0
    if inputs.out is None:
        raise ValueError("anigs static: --out is required (unless --plan-only)")
    out = run(inputs, cfg)
    metrics = out.metrics()
    held = held_out_text(metrics.get("test_psnr"), metrics.get("test_ssim"))
    if "imported" in metrics:
        im = metrics["imported"]
        print(f"static: imported {metrics['num_gaussians']} Gaussians (SH {metrics['sh_degree']}) from {im['path']} in "
              f"the {im['frame']} frame ({im['frame_source']}), {held}, train PSNR {metrics['train_psnr']:.2f} dB at "
              f"{metrics['image_size'][0]}x{metrics['image_size'][1]} -> {out.path('canonical')}")
        return 0
    print(f"static fit: {metrics['num_gaussians']} Gaussians, {held}, train PSNR {metrics['train_psnr']:.2f} dB, "
          f"{metrics['seconds']:.0f} s -> {out.path('canonical')}")
    return 0
