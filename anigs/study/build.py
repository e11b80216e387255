"""``anigs study build``: a self-contained 2AFC study folder from the camera-fixed final videos.

Written to ``out``, laid out as :class:`anigs.study.layout.Outputs` says: the page (the manifest
inlined, so it also works from file://), its script and style (package data ``assets/``), the
manifest (for ``anigs study serve`` and ``anigs study tally``), each distinct video once, named by
content hash (names do not reveal the method), and a README.

Each trial pairs ours (variant ``full`` by default) with one other variant on the same scene and
view; the page shuffles the trials and counterbalances left/right per participant from a seed
derived from the study seed and the participant id.
"""
from __future__ import annotations

import hashlib
from html import escape
import json
import random
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from anigs.io import atomic_write_text, write_json
from anigs.study.catch import CATCH, make_catch_video
from anigs.study.layout import Outputs
from anigs.study.schema import MANIFEST_SCHEMA, QUESTIONS
from anigs.reports.tables import variant_label

ASSETS = Path(__file__).with_name("assets")  # the page (study.html), its script and style
PAGE = "study.html"


@dataclass
class StudyOptions:
    """What ``build_study`` needs besides the videos."""

    ours: str = "full"
    others: list[str] | None = None  # None: every other variant found
    seed: int = 0  # study seed; the page mixes it with the participant id
    max_views: int = 0  # views per scene and comparison (0 = all shared views; else a seeded subset)
    min_plays: int = 1  # complete loops both videos must play before the answers count
    catch_trials: int = 0  # attention checks: ours against a blurred copy (anigs.study.catch)
    post_url: str | None = "answers"  # relative to the page (the study server), absolute, or None
    title: str = "Video comparison study"
    labels: dict[str, str] = field(default_factory=dict)  # variant -> label in Table 4


def video_info(path: Path) -> dict[str, Any]:
    """Size, fps and duration of a video (read from its header by ffmpeg)."""
    import imageio_ffmpeg

    gen = imageio_ffmpeg.read_frames(str(path))
    try:
        meta = next(gen)
    except Exception as exc:  # noqa: BLE001 - ffmpeg's own message is the useful part
        raise ValueError(f"study: cannot read video {path}: {exc}") from exc
    finally:
        gen.close()
    return {"size": list(meta["size"]), "fps": float(meta["fps"]), "duration": float(meta["duration"]),
            "codec": meta.get("codec")}


def _sha(data: bytes, n: int = 12) -> str:
    return hashlib.sha256(data).hexdigest()[:n]


def default_label(variant: str) -> str:
    return variant_label(variant)


def plan_trials(videos: Mapping[tuple[str, str], Mapping[str, Path]], opts: StudyOptions) -> list[dict[str, Any]]:
    """Trials (ours vs other, same scene and view), in a fixed canonical order."""
    scenes = list(dict.fromkeys(s for s, _ in videos))
    rng = random.Random(opts.seed)
    trials = []
    for scene in scenes:
        if (scene, opts.ours) not in videos:
            raise ValueError(f"study: no videos of ours (variant {opts.ours!r}) for scene {scene!r}")
        others = opts.others if opts.others is not None else [v for s, v in videos if s == scene and v != opts.ours]
        if not others:
            raise ValueError(f"study: scene {scene!r} has no variant to compare with {opts.ours!r}")
        for other in others:
            if other in (opts.ours, CATCH):
                raise ValueError(f"study: variant {other!r} cannot be compared with itself")
            if (scene, other) not in videos:
                raise ValueError(f"study: no videos of variant {other!r} for scene {scene!r}")
            shared = sorted(set(videos[(scene, opts.ours)]) & set(videos[(scene, other)]))
            if not shared:
                raise ValueError(f"study: {opts.ours!r} and {other!r} share no view on scene {scene!r}")
            if opts.max_views and len(shared) > opts.max_views:
                shared = sorted(rng.sample(shared, opts.max_views))
            for view in shared:
                trials.append({"id": f"{scene}/{view}/{other}", "scene": scene, "view": view,
                               "ours": opts.ours, "other": other})
    pool = [(s, v) for s in scenes for v in sorted(videos[(s, opts.ours)])]
    for scene, view in sorted(rng.sample(pool, min(opts.catch_trials, len(pool)))):
        trials.append({"id": f"{scene}/{view}/{CATCH}", "scene": scene, "view": view, "ours": opts.ours,
                       "other": CATCH, "catch": True})
    return trials


def _copy_videos(trials: list[dict[str, Any]], vids: Mapping[tuple[str, str], Mapping[str, Path]],
                 out: Path) -> dict[str, dict[str, Any]]:
    """Copy each distinct video once as videos/<content hash>; fill the trials' videos, size, fps."""
    copied: dict[Path, str] = {}
    infos: dict[str, dict[str, Any]] = {}
    for t in trials:
        t["videos"] = {}
        for variant in (t["ours"], t["other"]):
            src = vids[(t["scene"], variant)][t["view"]]
            if src not in copied:
                if not src.is_file():
                    raise FileNotFoundError(f"study: video not found: {src}")
                name = f"videos/{_sha(src.read_bytes())}{src.suffix.lower()}"
                if not (out / name).exists():
                    shutil.copyfile(src, out / f"{name}.tmp")
                    (out / f"{name}.tmp").replace(out / name)
                copied[src] = name
                infos[name] = video_info(src)
            t["videos"][variant] = copied[src]
        a, b = (infos[t["videos"][v]] for v in (t["ours"], t["other"]))
        if a["size"] != b["size"]:
            raise ValueError(f"study: pair {t['id']}: {t['ours']} is {a['size']} pixels but {t['other']} is "
                             f"{b['size']}; render both at the same size")
        t["size"], t["fps"] = a["size"], a["fps"]
        t["duration"] = max(a["duration"], b["duration"])
    return infos


def build_study(videos: Mapping[tuple[str, str], Mapping[str, str | Path]], out: str | Path,
                opts: StudyOptions | None = None) -> dict[str, Any]:
    """Write the study folder ``out`` (see the module doc) and return its manifest.

    ``videos``: {(scene, variant): {view: mp4 path}}, e.g. from :func:`anigs.stages.final.find_final_videos`.
    Raises ValueError when a pair's two videos differ in size (they would not be comparable).
    """
    opts = opts or StudyOptions()
    if opts.min_plays < 0:
        raise ValueError(f"study: min_plays must be >= 0, got {opts.min_plays}")
    vids = {k: {view: Path(p) for view, p in d.items()} for k, d in videos.items()}
    trials = plan_trials(vids, opts)
    layout = Outputs(out)
    out = layout.root
    layout.path("videos").mkdir(parents=True, exist_ok=True)
    temp: list[Path] = []
    try:
        for t in trials:
            if t.get("catch"):
                src = vids[(t["scene"], t["ours"])][t["view"]]
                dst = out / f".{t['scene']}-{t['view']}.{CATCH}.mp4"
                temp.append(dst)
                t["blur_sigma"] = make_catch_video(src, dst, video_info(src)["fps"])
                vids.setdefault((t["scene"], CATCH), {})[t["view"]] = dst
        infos = _copy_videos(trials, vids, out)
    finally:
        for f in temp:
            f.unlink(missing_ok=True)
    for stale in layout.path("videos").iterdir():  # a rebuild leaves no video of an earlier study behind
        if f"videos/{stale.name}" not in infos:
            stale.unlink()
    variants = list(dict.fromkeys([opts.ours] + [t["other"] for t in trials if not t.get("catch")]))
    core = {"ours": opts.ours, "seed": opts.seed, "questions": list(QUESTIONS),
            "trials": [{k: t[k] for k in ("id", "scene", "view", "ours", "other", "videos")} for t in trials]}
    manifest = {
        "schema": MANIFEST_SCHEMA,
        "study_id": _sha(json.dumps(core, sort_keys=True).encode()),
        "title": opts.title, "ours": opts.ours, "seed": opts.seed, "min_plays": opts.min_plays,
        "post_url": opts.post_url,
        "questions": [{"id": q, "text": text, "section": section} for q, (text, section) in QUESTIONS.items()],
        "labels": {v: opts.labels.get(v) or default_label(v) for v in variants},
        "scenes": list(dict.fromkeys(t["scene"] for t in trials)),
        "catch_trials": sum(bool(t.get("catch")) for t in trials),
        "comparisons": [v for v in variants if v != opts.ours],
        "trials": trials,
    }
    write_json(layout.path("manifest"), manifest)
    for key in ("script", "style"):
        atomic_write_text(layout.path(key), (ASSETS / layout.path(key).name).read_text())
    inline = json.dumps(manifest, indent=1).replace("</", "<\\/")  # safe inside <script>
    html = (ASSETS / PAGE).read_text()
    html = html.replace("{{TITLE}}", escape(opts.title)).replace("{{MANIFEST}}", inline)
    atomic_write_text(layout.path("page"), html)
    atomic_write_text(layout.path("readme"), README.format(
        n=len(trials), q=len(QUESTIONS), sid=manifest["study_id"],
        **{k: layout.LAYOUT[k].name for k in ("answers", "page", "manifest")}))
    written = [layout.path(k) for k in ("page", "script", "style", "manifest", "readme")]
    for f in [*written, *layout.path("videos").iterdir()]:
        f.chmod(0o644)  # readable by any web server (temporary files are created private)
    return manifest


README = """anigs 2AFC study ({n} pairs x {q} questions, study id {sid})

Serve it (answers are posted to {answers} next to this file):
    anigs study serve --dir . --port 8000      then open http://127.0.0.1:8000/
or open {page} directly and collect the files participants download at the end.
Tally (Table 4):
    anigs study tally {answers} *.json --manifest {manifest} --out tables/
"""
