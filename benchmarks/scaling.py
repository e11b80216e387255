"""How each stage's cost grows with the size of the capture and of the animation (issue 28).

One axis at a time grows from the demo (48 photos at 320x240, 30k Gaussians, views 256x192,
25 frames, 12 views queued); every point runs the real stage commands (``anigs <stage> ...``,
what the workflow's rules run) in fresh processes and records each one's wall seconds, CPU
seconds (user + sys of the process and its children, from ``wait4``) and peak RSS. Then the
growth exponent per stage and axis: the slope of log(CPU s) (and log(peak RSS)) against
log(axis value), least squares over the axis' points.

Axes and their stages:

  photos     24 48 96 192 384 photos (synthetic captures of the same garden, 320x240)
             capture, sfm, static
  photo_res  320 640 1280 px on the long side (``--res-photos`` photos, 4:3)  capture, sfm, static
  gaussians  30k 100k 300k 1M (the demo's fitted model, each Gaussian split into jittered
             copies; the dynamic set repeated)                     render_clip, refine, update
  view_res   256 512 1024 px on the long side (the demo's queued views' cameras rescaled, their
             masks resized)                                        render_clip, refine, update
  frames     25 49 121 frames per clip                             render_clip, refine, update
  views      6 12 24 views queued: the last round's update trains on all of them (the demo's
             12 views, repeated under new ids)                     render_clip, refine, update

The animation axes run round 1 of the demo's ``full`` variant on a finished demo run (``--scene``,
default results/demo): one view rendered with the static model (render_clip) and refined (refine),
their cost per view; then the update on the round's 3 views (on the views axis: all queued views),
the refined clip standing for each of them (the update's cost does not depend on the content).
The photo axes run a fresh capture per point. What was cut for time is a flag:
``--static-iterations`` (default 200: the static fit's per-step cost is what grows, the demo runs
1000), ``--update-steps`` (default 40; the demo 120 per round), ``--sfm-params`` (extra sfm keys,
e.g. a feature budget). ``--full`` runs every point of every axis at the demo's settings.

    python benchmarks/scaling.py --scene results/demo --out /tmp/scaling            # the default subset
    python benchmarks/scaling.py --axes photos --points 24,48,96 --out /tmp/scaling  # one axis
    python benchmarks/scaling.py --full --scene results/demo --out /tmp/scaling-full # the whole grid
    python benchmarks/scaling.py --report --out /tmp/scaling                         # tables only
    python benchmarks/scaling.py --smoke --out /tmp/scaling-smoke                     # tiny (tests)

Points already in ``OUT/results.jsonl`` are not run again (delete the file to re-measure).
Prints markdown tables (per point; exponents) and writes them to ``OUT/scaling.md``.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from anigs.stages.capture import Outputs as CaptureOutputs  # capture and sfm import no torch (see measure())
from anigs.stages.sfm import Outputs as SfmOutputs

ROOT = Path(__file__).resolve().parents[1]

# axis -> (the demo's value, the full grid, the default subset, stages)
AXES: dict[str, tuple[int, list[int], list[int], list[str]]] = {
    "photos": (48, [24, 48, 96, 192, 384], [24, 48, 96], ["capture", "sfm", "static"]),
    "photo_res": (320, [320, 640, 1280], [320, 640, 1280], ["capture", "sfm", "static"]),
    "gaussians": (30_000, [30_000, 100_000, 300_000, 1_000_000], [30_000, 100_000, 300_000],
                  ["render_clip", "refine", "update"]),
    "view_res": (256, [256, 512, 1024], [256, 512, 1024], ["render_clip", "refine", "update"]),
    "frames": (25, [25, 49, 121], [25, 49, 121], ["render_clip", "refine", "update"]),
    "views": (12, [6, 12, 24], [6, 12, 24], ["render_clip", "refine", "update"]),
}
PHOTO_AXES = ("photos", "photo_res")
SMOKE = {"photos": [6, 8, 12]}  # tiny captures of a tiny garden: the machinery, not the figures


# ---------------------------------------------------------------------------- measuring
def measure(cmd: list[str], log: Path, env: dict | None = None) -> dict:
    """Run ``cmd`` (stdout+stderr to ``log``); its wall s, CPU s (user+sys, children included) and
    peak RSS (MiB, the largest of the process and its waited-for children). Raises on failure.

    Linux counts the launching process' resident memory at the moment of the fork into the child's
    peak (the image replaced by exec), so this process stays small: numpy and yaml, no torch
    (about 40 MiB, the floor of every figure)."""
    log.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    with open(log, "w") as f:
        proc = subprocess.Popen(cmd, stdout=f, stderr=subprocess.STDOUT, env=env, cwd=ROOT)
        _, status, ru = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        tail = log.read_text(errors="replace")[-2000:]
        raise RuntimeError(f"{' '.join(cmd[:3])} ... failed ({proc.returncode}); log {log}:\n{tail}")
    return {"wall_s": wall, "cpu_s": ru.ru_utime + ru.ru_stime, "rss_mib": ru.ru_maxrss / 1024.0,
            "load": os.getloadavg()[0]}


def fit_exponent(xs, ys) -> float:
    """Least-squares slope of log(y) against log(x) (NaN with fewer than 2 distinct points)."""
    xs, ys = np.asarray(xs, float), np.asarray(ys, float)
    ok = (xs > 0) & (ys > 0) & np.isfinite(ys)
    if len(set(xs[ok])) < 2:
        return float("nan")
    return float(np.polyfit(np.log(xs[ok]), np.log(ys[ok]), 1)[0])


# ---------------------------------------------------------------------------- config
def demo_sections(scene_name: str = "demo") -> tuple[dict, dict, callable]:
    """The workflow config, the scene and ``sec(name)``: the effective section (as the rules' jparams)."""
    import yaml

    from anigs.config import load_scene, section

    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    with open(ROOT / "workflow" / "schemas" / "config.schema.yaml") as f:
        schema = yaml.safe_load(f)
    scene = load_scene(ROOT / config["scene_dir"], scene_name, schema)
    return config, scene, lambda name: section(config, scene, "full", name, schema)


def anigs_cmd(threads: int, stage: str, *args: str) -> list[str]:
    return [sys.executable, "-m", "anigs.cli", "--threads", str(threads), stage, *args]


# ---------------------------------------------------------------------------- the photo axes
def photo_point(axis: str, value: int, args, work: Path) -> dict[str, dict]:
    """capture -> sfm -> static for one point of the photo axes; {stage: figures}."""
    config, scene, sec = demo_sections()
    synth = json.loads(json.dumps(scene["synthetic"]))
    cap = synth["capture"]
    if axis == "photos":
        cap["num_images"] = value
    else:
        cap["num_images"] = args.res_photos
        cap["width"], cap["height"] = value, value * 3 // 4
    if args.smoke:
        synth["scene"]["num_gaussians"] = 3000
        cap["width"], cap["height"] = 96, 72
    d = work / f"{axis}-{value}"
    shutil.rmtree(d, ignore_errors=True)
    out: dict[str, dict] = {}
    out["capture"] = measure(anigs_cmd(args.threads, "capture", "--params", json.dumps(synth), "--out",
                                       str(d / "capture")), d / "capture.log")
    if args.smoke:
        return out  # SfM needs real-sized photos
    sfm = {**sec("sfm"), **json.loads(args.sfm_params)}
    capture, sfm_out = CaptureOutputs(d / "capture"), SfmOutputs(d / "sfm")
    out["sfm"] = measure(anigs_cmd(args.threads, "sfm", "--images", str(capture.path("images")), "--out",
                                   str(sfm_out.root), "--gt-cameras", str(capture.path("gt_cameras")),
                                   "--params", json.dumps(sfm)), d / "sfm.log")
    static = sec("static")  # the run's device and seed handed in
    if args.static_iterations:
        static["iterations"] = args.static_iterations
    out["static"] = measure(anigs_cmd(args.threads, "static", "--images", str(sfm_out.path("images")),
                                      "--cameras", str(sfm_out.path("cameras")), "--points",
                                      str(sfm_out.path("points")), "--out", str(d / "static"),
                                      "--params", json.dumps(static), "--no-progress"), d / "static.log")
    m = in_child("static_metrics", str(d / "static"))
    out["static"].update(test_psnr=m["test_psnr"], num_gaussians=m["num_gaussians"])
    if not args.keep:
        for sub in ("capture/images", "sfm/images"):
            shutil.rmtree(d / sub, ignore_errors=True)
    return out


# ---------------------------------------------------------------------------- the animation axes
def split_gaussians(ply: Path, n: int, out: Path, seed: int = 0) -> np.ndarray:
    """Write ``n`` Gaussians made from the model in ``ply``: each split into k = ceil(n / N) copies
    jittered by its own scale, scales shrunk by k^(1/3) (the same volume); returns the source row
    of each written Gaussian [n] (to repeat per-Gaussian arrays)."""
    import torch

    from anigs.gaussians import Gaussians, load_ply

    g = load_ply(ply)
    k = max(1, math.ceil(n / g.num))
    idx = torch.arange(g.num).repeat(k)[:n]
    gen = torch.Generator().manual_seed(seed)
    p = {name: t[idx].clone() for name, t in g.params().items()}
    if k > 1:
        sigma = p["log_scales"].exp()
        p["means"] = p["means"] + torch.randn(p["means"].shape, generator=gen) * sigma
        p["log_scales"] = p["log_scales"] - math.log(k) / 3
    Gaussians(**p).save_ply(out)
    return idx.numpy()


def in_child(func: str, *args):
    """``func(*args)`` of this module run in a child process, its JSON result: the stages' ``Outputs``
    of the animation import torch, and this process stays small (see :func:`measure`)."""
    code = ("import json, sys; sys.path.insert(0, sys.argv[1]); import scaling; "
            "print(json.dumps(getattr(scaling, sys.argv[2])(*json.loads(sys.argv[3]))))")
    res = subprocess.run([sys.executable, "-c", code, str(Path(__file__).parent), func, json.dumps(args)],
                         check=True, cwd=ROOT, stdout=subprocess.PIPE, text=True)
    return json.loads(res.stdout.splitlines()[-1])


def static_metrics(folder: str) -> dict:
    """The static stage's metrics in ``folder`` (through its ``Outputs``; run by :func:`in_child`)."""
    from anigs.stages.static import Outputs as StaticOutputs

    return StaticOutputs(folder).metrics()


def animation_inputs(axis: str, value: int, scene_dir: str, point_dir: str) -> dict[str, list[str]]:
    """The point's static, views and masks stage folders under ``point_dir`` (through the stages'
    ``Outputs``), from the demo's in ``scene_dir``; returns the view ids the update trains on and
    their target clips in the round's folder (run by :func:`in_child`)."""
    from PIL import Image

    from anigs.stages.masks import Outputs as MasksOutputs
    from anigs.stages.refine import Outputs as RefineOutputs
    from anigs.stages.static import Outputs as StaticOutputs
    from anigs.stages.views import Outputs as ViewsOutputs

    scene, d = Path(scene_dir), Path(point_dir)
    src_views, src_masks = ViewsOutputs(scene / "views"), MasksOutputs(scene / "masks")
    static, views_out, masks = StaticOutputs(d / "static"), ViewsOutputs(d / "views"), MasksOutputs(d / "masks")
    views = src_views.json("views")
    ply = StaticOutputs(scene / "static").path("canonical")
    dyn, labels = src_masks.dynamic(), src_masks.effect_labels()
    for folder in (static, views_out, masks):
        folder.root.mkdir(parents=True, exist_ok=True)
    if axis == "gaussians" and value != AXES["gaussians"][0]:
        idx = split_gaussians(ply, value, static.path("canonical"))
        dyn, labels = dyn[idx], labels[idx]
    else:
        shutil.copyfile(ply, static.path("canonical"))
    base_views = views["views"]
    if axis == "views":  # the queue repeated under new ids (the same cameras)
        views["views"] = [dict(base_views[i % len(base_views)], id=f"v{i:02d}") for i in range(value)]
    scale = value / 256 if axis == "view_res" else 1.0
    for v in views["views"]:
        src = [b for b in base_views if b["camera"]["name"] == v["camera"]["name"]][0]["id"]
        cam = dict(v["camera"])
        if scale != 1.0:
            cam["width"], cam["height"] = round(cam["width"] * scale), round(cam["height"] * scale)
            cam["K"] = [[x * scale for x in cam["K"][0]], [x * scale for x in cam["K"][1]], cam["K"][2]]
        v["camera"] = cam
        m = Image.open(src_masks.path("mask", view=src))
        if scale != 1.0:
            m = m.resize((cam["width"], cam["height"]), Image.NEAREST)
        m.save(masks.path("mask", view=v["id"]))
    np.save(masks.path("dynamic"), dyn)
    np.save(masks.path("effect_labels"), labels)
    views_out.path("views").write_text(json.dumps(views))
    ids = [v["id"] for v in views["views"]]
    ids = ids if axis == "views" else ids[:3]
    round_dir = RefineOutputs(d / "round1")
    return {"ids": ids, "targets": [str(round_dir.path("target", view=v)) for v in ids]}


def animation_point(axis: str, value: int, args, work: Path) -> dict[str, dict]:
    """Round 1 of the demo at one point: render_clip and refine per view, then the update."""
    config, scene, sec = demo_sections()
    d = work / f"{axis}-{value}"
    shutil.rmtree(d, ignore_errors=True)
    point = in_child("animation_inputs", axis, value, str(args.scene), str(d))
    ids, targets = point["ids"], point["targets"]
    frames = value if axis == "frames" else sec("animate")["frames"]
    render_p = {**sec("render_clip"), "num_frames": frames, "device": config["device"]}
    refine_p = {**sec("refine"), "prompt": scene.get("prompt", ""), "seed": config["seed"],
                "effects": list(sec("effects")["requested"]) if sec("effects")["requested"] != "auto" else []}
    update_p = {**sec("update"), "device": config["device"], "seed": config["seed"] + 1000,
                "steps": args.update_steps or sec("update")["steps"]}
    out: dict[str, dict] = {}
    rd = d / "round1"  # the round's folder (the render_clip, refine and update stages' files)
    for v in ids[:1]:  # render_clip and refine cost the same for every view: one is measured
        r = measure(anigs_cmd(1, "render_clip", "--static", str(d / "static"), "--views", str(d / "views"),
                              "--view-id", v, "--out", str(rd), "--params", json.dumps(render_p)),
                    d / "logs" / f"render_clip_{v}.log")
        f = measure(anigs_cmd(1, "refine", "--render-clip", str(rd), "--masks", str(d / "masks"), "--round", "1",
                              "--view", v, "--out", str(rd), "--params", json.dumps(refine_p)),
                    d / "logs" / f"refine_{v}.log")
        _add(out, "render_clip", r)
        _add(out, "refine", f)
    for dst in targets[1:]:  # the update trains on every view of the round: the refined clip stands for each
        shutil.copyfile(targets[0], dst)
    # round 1 of a plan of several rounds: no containment (the workflow contains only the final round's update)
    out["update"] = measure(anigs_cmd(args.threads, "update", "--static", str(d / "static"), "--targets", *targets,
                                      "--views", str(d / "views"), "--masks", str(d / "masks"), "--round", "1",
                                      "--rounds", "2", "--out", str(rd), "--params",
                                      json.dumps(update_p)), d / "logs" / "update.log")
    if not args.keep:
        shutil.rmtree(rd / "render", ignore_errors=True)
        shutil.rmtree(Path(targets[0]).parent, ignore_errors=True)
    return out


def _add(acc: dict, stage: str, r: dict) -> None:
    if stage not in acc:
        acc[stage] = dict(r)
    else:
        a = acc[stage]
        a["wall_s"] += r["wall_s"]
        a["cpu_s"] += r["cpu_s"]
        a["rss_mib"] = max(a["rss_mib"], r["rss_mib"])
        a["load"] = max(a["load"], r["load"])


# ---------------------------------------------------------------------------- report
def load_results(path: Path) -> list[dict]:
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def _fmt(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{round(x, 2) + 0.0:.2f}"  # no -0.00


def report(rows: list[dict]) -> str:
    """Markdown: one table per axis (stage: CPU s / wall s / peak RSS MiB), then the exponents.
    A point measured more than once (other settings) counts with its last measurement."""
    rows = list({(r["axis"], r["value"]): r for r in rows}.values())
    lines: list[str] = []
    expo: dict[tuple[str, str], tuple[float, float, int]] = {}
    for axis in AXES:
        pts = sorted((r for r in rows if r["axis"] == axis), key=lambda r: r["value"])
        if not pts:
            continue
        stages = [s for s in AXES[axis][3] if any(s in r["stages"] for r in pts)]
        lines += [f"\n**{axis}** (CPU s / wall s / peak RSS MiB; load = 1-min load average at the end)\n",
                  "| " + axis + " | " + " | ".join(stages) + " | load |",
                  "|---" * (len(stages) + 2) + "|"]
        for r in pts:
            cells = []
            for s in stages:
                f = r["stages"].get(s)
                cells.append("-" if f is None else f"{f['cpu_s']:.1f} / {f['wall_s']:.1f} / {f['rss_mib']:.0f}")
            load = max(f["load"] for f in r["stages"].values())
            lines.append(f"| {r['value']:,} | " + " | ".join(cells) + f" | {load:.1f} |")
        for s in stages:
            have = [r for r in pts if s in r["stages"]]
            xs = [r["value"] for r in have]
            cpu = [r["stages"][s]["cpu_s"] for r in have]
            expo[(axis, s)] = (fit_exponent(xs, cpu), fit_exponent(xs, [r["stages"][s]["rss_mib"] for r in have]),
                               len(have), fit_exponent(xs[-2:], cpu[-2:]))
    if expo:
        lines += ["\n**Growth exponents** (slope of log CPU s / log peak RSS against log axis value, least squares "
                  "over the points; and of CPU s between the two largest points, where a process' fixed start-up "
                  "cost weighs least)\n",
                  "| axis | stage | CPU exponent | CPU, two largest | RSS exponent | points |", "|---|---|---|---|---|---|"]
        for (axis, s), (c, m, n, c2) in expo.items():
            lines.append(f"| {axis} | {s} | {_fmt(c)} | {_fmt(c2)} | {_fmt(m)} | {n} |")
        worst = max(((k, v) for k, v in expo.items() if math.isfinite(v[0])), key=lambda kv: kv[1][0], default=None)
        if worst:
            lines.append(f"\nWorst-growing: {worst[0][1]} along {worst[0][0]} (CPU exponent {worst[1][0]:.2f}).")
    return "\n".join(lines)


def _shared_base(axis: str, value: int, setup: str, rows: list[dict]) -> dict | None:
    """The same run measured on another axis (same settings): the demo's point of the animation
    axes but views (whose update trains on all 12 queued views, not the round's 3); on the photo
    axes, ``--res-photos`` photos at 320 px."""
    same = {(a, AXES[a][0]) for a in AXES if a not in PHOTO_AXES and a != "views"}
    if axis in PHOTO_AXES:
        n = json.loads(setup)["res_photos"]
        same = {("photos", n), ("photo_res", AXES["photo_res"][0])}
    if (axis, value) not in same:
        return None
    for r in rows:
        if (r["axis"], r["value"]) in same and r.get("setup") == setup:
            return r
    return None


# ---------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, required=True, help="results.jsonl, scaling.md, per-point work folders")
    ap.add_argument("--axes", default=None, help=f"comma-separated subset of {','.join(AXES)} (default: all)")
    ap.add_argument("--points", default=None, help="comma-separated values for the (one) axis in --axes")
    ap.add_argument("--full", action="store_true", help="every point of every axis at the demo's settings")
    ap.add_argument("--smoke", action="store_true", help="tiny captures (6, 8, 12 photos at 96x72): the machinery")
    ap.add_argument("--report", action="store_true", help="only print the tables from OUT/results.jsonl")
    ap.add_argument("--scene", default=str(ROOT / "results" / "demo"), help="a finished demo run (animation axes)")
    ap.add_argument("--threads", type=int, default=2, help="anigs --threads of the multi-threaded stages")
    ap.add_argument("--res-photos", type=int, default=24, help="photos per capture on the photo_res axis")
    ap.add_argument("--static-iterations", type=int, default=200, help="static fit iterations (0: the demo's)")
    ap.add_argument("--update-steps", type=int, default=40, help="update steps (0: the demo's)")
    ap.add_argument("--sfm-params", default="{}", help="extra sfm keys as JSON, e.g. '{\"max_num_features\": 2048}'")
    ap.add_argument("--keep", action="store_true", help="keep images and clips of each point")
    args = ap.parse_args(argv)
    if args.full:
        args.static_iterations = args.update_steps = 0
        args.res_photos = AXES["photos"][0]
    args.out.mkdir(parents=True, exist_ok=True)
    results = args.out / "results.jsonl"
    axes = args.axes.split(",") if args.axes else (list(SMOKE) if args.smoke else list(AXES))
    for a in axes:
        if a not in AXES:
            ap.error(f"unknown axis {a!r} (have {', '.join(AXES)})")
    if args.points and len(axes) != 1:
        ap.error("--points needs exactly one axis in --axes")
    if not args.report:
        if any(a not in PHOTO_AXES for a in axes) and not (Path(args.scene) / "masks").is_dir():
            ap.error(f"--scene {args.scene}: no finished demo run there (no masks folder); run `snakemake` first")
        done = {(r["axis"], r["value"], r.get("setup")) for r in load_results(results)}
        setup = json.dumps({k: getattr(args, k) for k in ("smoke", "static_iterations", "update_steps", "res_photos",
                                                            "sfm_params", "threads")}, sort_keys=True)
        for a in axes:
            values = ([int(float(x)) for x in args.points.split(",")] if args.points else
                      SMOKE[a] if args.smoke else AXES[a][1] if args.full else AXES[a][2])
            for v in values:
                if (a, v, setup) in done:
                    continue
                base = _shared_base(a, v, setup, load_results(results))
                if base is not None:  # the demo's point is the same run on every animation axis
                    with open(results, "a") as f:
                        f.write(json.dumps({**base, "axis": a, "value": v}) + "\n")
                    continue
                run = photo_point if a in PHOTO_AXES else animation_point
                print(f"{a} = {v} ...", file=sys.stderr, flush=True)
                stages = run(a, v, args, args.out / "work")
                with open(results, "a") as f:
                    f.write(json.dumps({"axis": a, "value": v, "setup": setup, "stages": stages}) + "\n")
    text = report(load_results(results))
    (args.out / "scaling.md").write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
