"""Stage ``update``: the model update of one round (train the deformation field on its targets).

    anigs update --canonical static/canonical.ply [--init-model round{r-1}/model.pt] \\
        --targets round{r}/target/A.npz round{r}/target/B.npz \\
        [--view-json views/views.json [--view-ids A B] | --camera-json A.json B.json] \\
        [--static-refs refA.png refB.png] --dynamic dynamic.npy [--effect-labels effect_labels.npy] \\
        --out round{r}/model.pt [--log-json round{r}/update.json] --params '{...update section...}' \\
        [--prior ltx --prior-params '{...}' --prompt "trees swaying"]   # only when lambda_sds > 0

Cameras: from ``--camera-json`` (one per target), else from ``--view-json`` with ``--view-ids``
(default: the targets' file stems), else from each target clip's metadata (``camera``).
Static references (for L_cano): ``--static-refs`` images (.png, .npy [H,W,3], or .npz clip: frame 0),
else renders of the canonical PLY. ``--dynamic``: .npy [N] bool (or int effect labels, 0 = static).
``--effect-labels``: the masks stage's ``effect_labels.npy`` (int [N], 0 on exactly the static
Gaussians of ``--dynamic``): which effect each dynamic Gaussian belongs to, for the per-effect
settings ``effect_num_bases`` and ``effect_limits``.
If the update diverges, the last good state is written to ``<out stem>.last_good.pt`` next to ``--out``.

``--masks DIR`` (the masks stage's folder, ``{view}.png``) with ``contain`` (default): after training,
the dynamic Gaussians whose motion carries their footprint out of a view's mask (dilated by
``contain_margin_px``) in any frame, for every view of ``--view-json`` (else the targets' views),
move less (half, then a quarter) until they stay inside, or else stay still: their coefficients
are dropped and their canonical position is the static fit's again
(:func:`anigs.masks.contain.contain_motion`); ``update.json`` reports how many. The workflow passes
``--masks`` to the final round's update only (``contain_rounds: final``; ``every`` for all rounds).
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np
import torch
from anigs.animate.update import UpdateConfig

Config = UpdateConfig  # the `update` config section

log = logging.getLogger("anigs.update")


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
        from anigs.images import load_image

        img = load_image(p)
    if img.ndim != 3 or img.shape[-1] != 3 or not np.isfinite(img).all():
        raise ValueError(f"static reference {p}: expected a finite [H,W,3] image, got shape {img.shape}")
    return torch.from_numpy(np.ascontiguousarray(img))


def _cameras(targets: list[str], metas: list[dict], view_json: str | None, view_ids: list[str] | None,
             camera_json: list[str] | None):
    from anigs.cameras import Camera, load_camera_json, load_view_camera

    n = len(targets)
    if camera_json:
        if len(camera_json) != n:
            raise ValueError(f"update: {len(camera_json)} --camera-json files for {n} targets")
        return [load_camera_json(p) for p in camera_json]
    if view_json:
        ids = view_ids or [Path(t).stem for t in targets]
        if len(ids) != n:
            raise ValueError(f"update: {len(ids)} --view-ids for {n} targets")
        return [load_view_camera(view_json, i) for i in ids]
    cams = []
    for t, m in zip(targets, metas):
        if "camera" not in m:
            raise KeyError(f"update: target {t} has no camera in its metadata; pass --camera-json or --view-json")
        cams.append(Camera.from_dict(m["camera"]))
    return cams


def run(canonical_path: str | Path, targets: list[str], dynamic_path: str | Path, out: str | Path, cfg: UpdateConfig,
        init_model: str | None = None, view_json: str | None = None, view_ids: list[str] | None = None,
        camera_json: list[str] | None = None, static_refs: list[str] | None = None, sds_prior: str | None = None,
        sds_prior_params: dict | None = None, prompt: str = "", masks_dir: str | Path | None = None,
        effect_labels_path: str | Path | None = None) -> dict:
    """Train the deformation field (and canonical positions) on the round's ``targets``; writes the
    model to ``out`` and returns the training log (loss history, timing; with ``masks_dir``, the
    containment of the motion). ``effect_labels_path``: int [N] effect labels of the dynamic set
    (the masks stage's ``effect_labels.npy``), read by ``effect_num_bases`` and ``effect_limits``."""
    from anigs.animate.deform import load_model, save_model
    from anigs.animate.losses import prior_sds_hook
    from anigs.animate.update import ViewData, run_update
    from anigs.gaussians import Gaussians
    from anigs.video import load_clip

    canonical_ply = Gaussians.load_ply(canonical_path)
    dyn_path = Path(dynamic_path)
    if not dyn_path.exists():
        raise FileNotFoundError(f"dynamic selection not found: {dyn_path}")
    dynamic = torch.from_numpy(np.load(dyn_path))
    if dynamic.ndim != 1 or dynamic.shape[0] != canonical_ply.num:
        raise ValueError(f"{dyn_path}: shape {tuple(dynamic.shape)}, expected [{canonical_ply.num}] (one per Gaussian "
                         f"of {canonical_path})")
    if effect_labels_path is not None:
        labels = torch.from_numpy(np.load(effect_labels_path).astype(np.int64))
        if labels.shape != dynamic.shape or not torch.equal(labels != 0, dynamic != 0):
            raise ValueError(f"update: {effect_labels_path} (effect labels, shape {tuple(labels.shape)}) does not "
                             f"label exactly the dynamic Gaussians of {dyn_path}: re-run the masks stage")
        dynamic = labels
    clips, metas = [], []
    for t in targets:
        c, m = load_clip(t)
        clips.append(torch.from_numpy(c))
        metas.append(m)
    cams = _cameras(targets, metas, view_json, view_ids, camera_json)
    refs: list[torch.Tensor | None] = [None] * len(clips)
    if static_refs:
        if len(static_refs) != len(clips):
            raise ValueError(f"update: {len(static_refs)} --static-refs for {len(clips)} targets")
        refs = [_load_reference(p) for p in static_refs]
    elif cfg.lambda_cano > 0:
        from anigs.animate.update import static_references

        refs = static_references(canonical_ply, cams, torch.tensor(cfg.background, dtype=torch.float32), cfg.backend)
    views = [ViewData(c, clip, r) for c, clip, r in zip(cams, clips, refs)]

    canonical, init = canonical_ply, None
    if init_model:
        canonical, init, _ = load_model(init_model, canonical_ply)
    sds = None
    if cfg.lambda_sds > 0:
        if not sds_prior:
            raise ValueError("update: lambda_sds > 0 needs --prior (a video prior with a score, e.g. ltx)")
        from anigs.refine.prior import get_prior

        sds = prior_sds_hook(get_prior(sds_prior, sds_prior_params or {}), prompt, cfg.sds_frames)
    out = Path(out)
    result = run_update(canonical, dynamic, views, cfg, init=init, sds_fn=sds,
                        failure_path=out.with_name(out.stem + ".last_good.pt"))
    contained = None
    if masks_dir is not None and cfg.contain and result.deformation.num_dynamic:
        all_cams = cams
        if view_json:
            from anigs.io import read_json
            from anigs.views import cameras_from_views

            all_cams = cameras_from_views(read_json(view_json))
        contained = _contain(result, canonical_ply, all_cams, Path(masks_dir), cfg)
    save_model(out, result.deformation, result.canonical, cfg.to_dict(),
               store_all_attributes=cfg.param_groups == "all",
               extra={"targets": [str(t) for t in targets], "init_model": init_model,
                      "skipped": result.skipped})
    log.info("wrote %s (%d dynamic Gaussians, K=%d, T=%d)", out, result.deformation.num_dynamic,
             result.deformation.num_bases, result.deformation.num_frames)
    info = {"steps": result.steps, "seconds": result.seconds, "skipped": result.skipped,
            "num_dynamic": result.deformation.num_dynamic, "num_bases": result.deformation.num_bases,
            "num_frames": result.deformation.num_frames, "history": result.history, "config": cfg.to_dict()}
    if contained is not None:
        info["containment"] = contained
    return info


def _contain(result, static, cameras, masks_dir: Path, cfg: UpdateConfig) -> dict:
    """Shrink or stop (in ``result``) the motion of the dynamic Gaussians that leaves the dilated masks
    of ``cameras`` (:func:`anigs.masks.contain.contain_motion`); returns the counts for ``update.json``."""
    import time

    import torch

    from anigs.images import read_mask
    from anigs.masks.contain import contain_motion, scaled_motion

    t0 = time.perf_counter()
    missing = [c.name for c in cameras if not (masks_dir / f"{c.name}.png").is_file()]
    if missing:
        raise FileNotFoundError(f"update: no mask for views {missing} in {masks_dir} (containment needs one per view)")
    masks = [read_mask(masks_dir / f"{c.name}.png") >= 0.5 for c in cameras]
    d = result.deformation
    factor, _, worst = contain_motion(result.canonical, d, cameras, masks, cfg.contain_margin_px,
                                            cfg.contain_max_outside_px)
    keep = factor > 0
    info = {"margin_px": cfg.contain_margin_px, "max_outside_px": cfg.contain_max_outside_px,
            "dynamic_before": int(len(keep)), "dynamic_after": int(keep.sum()),
            "attenuated": {str(f): int((factor == f).sum()) for f in sorted(set(factor.tolist())) if 0 < f < 1},
            "frozen": int((~keep).sum()),
            "frozen_by_view": {c.name: int(((worst == k) & ~keep).sum()) for k, c in enumerate(cameras)}}
    if (factor < 1).any():
        d = scaled_motion(d, factor)
        k = torch.from_numpy(keep)
        frozen = d.dynamic_index[~k]
        sub = lambda lim: None if lim is None else lim[k]  # noqa: E731
        result.deformation = d.remapped(d.dynamic_index[k], sub(d.max_offset), sub(d.max_angle))
        for p in result.deformation.parameters():
            p.requires_grad_(False)
        if cfg.param_groups == "deformation+positions":  # a frozen Gaussian is the static fit's again
            c = result.canonical
            c.means = c.means.index_copy(0, frozen, static.means.detach()[frozen].to(c.means.dtype))
    info["seconds"] = round(time.perf_counter() - t0, 3)
    return info


# ---- command line: anigs update ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from anigs.cli import add_params, add_canonical, add_out

    add_canonical(p, help="canonical 3DGS PLY")
    p.add_argument("--init-model", default=None, help="model.pt of the previous round (omit: start from zero)")
    p.add_argument("--targets", nargs="+", default=None, help="target clips (.npz), one per training view")
    p.add_argument("--view-json", default=None, help="views JSON holding the cameras of the targets")
    p.add_argument("--view-ids", nargs="+", default=None, help="view ids of the targets (default: file stems)")
    p.add_argument("--camera-json", nargs="+", default=None, help="one camera JSON per target")
    p.add_argument("--static-refs", nargs="+", default=None, help="static reference images, one per target")
    p.add_argument("--dynamic", default=None, help=".npy [N] bool (or int labels) selecting dynamic Gaussians")
    p.add_argument("--effect-labels", default=None, help="int .npy [N]: the effect of each dynamic Gaussian (the masks "
                                                         "stage's effect_labels.npy: 0 static, 1 + region index), "
                                                         "for update.effect_num_bases and effect_limits")
    p.add_argument("--masks", default=None, help="the masks stage's folder ({view}.png): with update.contain, a Gaussian "
                                                 "whose motion leaves the dilated masks moves less or stays still")
    add_out(p, "output model.pt")
    p.add_argument("--log-json", default=None, help="write the loss history and timing here")
    add_params(p, "update")
    p.add_argument("--prior", default=None, help="video prior name for the SDS term (lambda_sds > 0)")
    p.add_argument("--prior-params", default=None, help="that prior's config section as JSON (or @file)")
    p.add_argument("--prompt", default="", help="text prompt for the SDS term")
    p.add_argument("--method", default="anigs", choices=("anigs", "lifting", "physics"),
                   help="anigs: train our deformation field; lifting / physics: fit that baseline instead "
                        "(anigs.baselines; same inputs, same model.pt format)")
    p.add_argument("--method-params", default=None, help="the baseline's config (animate.<method>) as JSON")
    p.add_argument("--still", default=None, metavar="REASON",
                   help="nothing to animate: write a model in which nothing moves (no targets; REASON is stored)")
    p.add_argument("--frames", type=int, default=None, help="with --still: frames T of the model (animate.frames)")


def main(args: argparse.Namespace) -> int:
    from anigs.cli import parse_params
    from anigs.io import write_json

    if args.still:
        from anigs.animate.still import write_still_model
        from anigs.animate.deform import resolve_num_bases

        if not args.frames:
            raise ValueError("update --still: give --frames T (animate.frames)")
        cfg = UpdateConfig.from_dict(parse_params(args.params))
        K = resolve_num_bases(cfg.num_bases, args.frames, log)
        info = write_still_model(args.canonical, args.out, args.frames, K, args.still)
        if args.log_json:
            write_json(args.log_json, info)
        return 0
    if not args.targets or not args.dynamic:
        raise ValueError("update: --targets and --dynamic are required (or --still REASON when nothing moves)")
    if args.method != "anigs":
        from anigs.baselines import run_baseline

        run_baseline(args.method, args.canonical, args.dynamic, args.targets, args.out,
                     parse_params(args.method_params), view_json=args.view_json, view_ids=args.view_ids,
                     log_json=args.log_json)
        return 0
    info = run(args.canonical, args.targets, args.dynamic, args.out, UpdateConfig.from_dict(parse_params(args.params)),
               init_model=args.init_model, view_json=args.view_json, view_ids=args.view_ids,
               camera_json=args.camera_json, static_refs=args.static_refs, sds_prior=args.prior,
               sds_prior_params=parse_params(args.prior_params), prompt=args.prompt, masks_dir=args.masks,
               effect_labels_path=args.effect_labels)
    if args.log_json:
        write_json(args.log_json, info)
    return 0
