"""``anigs update``: the model update of one round (train the deformation field on its targets).

    anigs update --canonical static/canonical.ply [--init-model round{r-1}/model.pt] \\
        --targets round{r}/target/A.npz round{r}/target/B.npz \\
        [--view-json views/views.json [--view-ids A B] | --camera-json A.json B.json] \\
        [--static-refs refA.png refB.png] --dynamic dynamic.npy \\
        --out round{r}/model.pt [--log-json round{r}/update.json] --params '{...update section...}' \\
        [--prior ltx --prior-params '{...}' --prompt "trees swaying"]   # only when lambda_sds > 0

Cameras: from ``--camera-json`` (one per target), else from ``--view-json`` with ``--view-ids``
(default: the targets' file stems), else from each target clip's metadata (``camera``).
Static references (for L_cano): ``--static-refs`` images (.png, .npy [H,W,3], or .npz clip: frame 0),
else renders of the canonical PLY. ``--dynamic``: .npy [N] bool (or int effect labels, 0 = static).
If the update diverges, the last good state is written to ``<out stem>.last_good.pt`` next to ``--out``.
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np
import torch

log = logging.getLogger("anigs.update")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--canonical", required=True, help="canonical 3DGS PLY")
    p.add_argument("--init-model", default=None, help="model.pt of the previous round (omit: start from zero)")
    p.add_argument("--targets", nargs="+", required=True, help="target clips (.npz), one per training view")
    p.add_argument("--view-json", default=None, help="views JSON holding the cameras of the targets")
    p.add_argument("--view-ids", nargs="+", default=None, help="view ids of the targets (default: file stems)")
    p.add_argument("--camera-json", nargs="+", default=None, help="one camera JSON per target")
    p.add_argument("--static-refs", nargs="+", default=None, help="static reference images, one per target")
    p.add_argument("--dynamic", required=True, help=".npy [N] bool (or int labels) selecting dynamic Gaussians")
    p.add_argument("--out", required=True, help="output model.pt")
    p.add_argument("--log-json", default=None, help="write the loss history and timing here")
    p.add_argument("--params", default=None, help="update config section as JSON (or @file)")
    p.add_argument("--prior", default=None, help="video prior name for the SDS term (lambda_sds > 0)")
    p.add_argument("--prior-params", default=None, help="that prior's config section as JSON (or @file)")
    p.add_argument("--prompt", default="", help="text prompt for the SDS term")


def _load_reference(path: str) -> torch.Tensor:
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"static reference not found: {p}")
    if p.suffix == ".npz":
        from anigs.video import load_clip

        img = load_clip(p)[0][0]
    elif p.suffix == ".npy":
        img = np.load(p).astype(np.float32)
    else:
        import imageio.v2 as imageio

        img = np.asarray(imageio.imread(p))
        img = img[..., :3].astype(np.float32) / (255.0 if img.dtype == np.uint8 else 1.0)
    if img.ndim != 3 or img.shape[-1] != 3 or not np.isfinite(img).all():
        raise ValueError(f"static reference {p}: expected a finite [H,W,3] image, got shape {img.shape}")
    return torch.from_numpy(np.ascontiguousarray(img))


def _cameras(args, metas: list[dict]):
    from anigs.cameras import Camera
    from anigs.commands.render_clip import load_camera_json, load_view_camera

    n = len(args.targets)
    if args.camera_json:
        if len(args.camera_json) != n:
            raise ValueError(f"update: {len(args.camera_json)} --camera-json files for {n} targets")
        return [load_camera_json(p) for p in args.camera_json]
    if args.view_json:
        ids = args.view_ids or [Path(t).stem for t in args.targets]
        if len(ids) != n:
            raise ValueError(f"update: {len(ids)} --view-ids for {n} targets")
        return [load_view_camera(args.view_json, i) for i in ids]
    cams = []
    for t, m in zip(args.targets, metas):
        if "camera" not in m:
            raise KeyError(f"update: target {t} has no camera in its metadata; pass --camera-json or --view-json")
        cams.append(Camera.from_dict(m["camera"]))
    return cams


def run(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params
    from anigs.deform import load_model, save_model
    from anigs.gaussians import Gaussians
    from anigs.io import write_json
    from anigs.losses import prior_sds_hook
    from anigs.update import UpdateConfig, ViewData, run_update
    from anigs.video import load_clip

    cfg = UpdateConfig.from_dict(parse_params(args.params))
    canonical_ply = Gaussians.load_ply(args.canonical)
    dyn_path = Path(args.dynamic)
    if not dyn_path.exists():
        raise FileNotFoundError(f"dynamic selection not found: {dyn_path}")
    dynamic = torch.from_numpy(np.load(dyn_path))
    if dynamic.ndim != 1 or dynamic.shape[0] != canonical_ply.num:
        raise ValueError(f"{dyn_path}: shape {tuple(dynamic.shape)}, expected [{canonical_ply.num}] (one per Gaussian "
                         f"of {args.canonical})")
    clips, metas = [], []
    for t in args.targets:
        c, m = load_clip(t)
        clips.append(torch.from_numpy(c))
        metas.append(m)
    cams = _cameras(args, metas)
    refs: list[torch.Tensor | None] = [None] * len(clips)
    if args.static_refs:
        if len(args.static_refs) != len(clips):
            raise ValueError(f"update: {len(args.static_refs)} --static-refs for {len(clips)} targets")
        refs = [_load_reference(p) for p in args.static_refs]
    elif cfg.lambda_cano > 0:
        from anigs.update import static_references

        refs = static_references(canonical_ply, cams, torch.tensor(cfg.background, dtype=torch.float32), cfg.backend)
    views = [ViewData(c, clip, r) for c, clip, r in zip(cams, clips, refs)]

    canonical, init = canonical_ply, None
    if args.init_model:
        canonical, init, _ = load_model(args.init_model, canonical_ply)
    sds = None
    if cfg.lambda_sds > 0:
        if not args.prior:
            raise ValueError("update: lambda_sds > 0 needs --prior (a video prior with a score, e.g. ltx)")
        from anigs.prior import get_prior

        sds = prior_sds_hook(get_prior(args.prior, parse_params(args.prior_params)), args.prompt, cfg.sds_frames)
    out = Path(args.out)
    result = run_update(canonical, dynamic, views, cfg, init=init, sds_fn=sds,
                        failure_path=out.with_name(out.stem + ".last_good.pt"))
    save_model(out, result.deformation, result.canonical, cfg.to_dict(),
               store_all_attributes=cfg.param_groups == "all",
               extra={"targets": [str(t) for t in args.targets], "init_model": args.init_model,
                      "skipped": result.skipped})
    if args.log_json:
        write_json(args.log_json, {"steps": result.steps, "seconds": result.seconds, "skipped": result.skipped,
                                   "num_dynamic": result.deformation.num_dynamic,
                                   "num_bases": result.deformation.num_bases,
                                   "num_frames": result.deformation.num_frames, "history": result.history,
                                   "config": cfg.to_dict()})
    log.info("wrote %s (%d dynamic Gaussians, K=%d, T=%d)", out, result.deformation.num_dynamic,
             result.deformation.num_bases, result.deformation.num_frames)
    return 0
