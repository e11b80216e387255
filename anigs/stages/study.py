"""``anigs study {build,serve,tally}``: the 2AFC user study (the paper's Table 4). The command lives in the stage
layer because ``build`` finds the final stage's folders (:func:`anigs.stages.final.find_final_videos`); the study
itself (:mod:`anigs.study`) knows no stage."""
from __future__ import annotations

import argparse
import logging
import signal
import threading
from pathlib import Path
from anigs.io import read_json
from anigs.stages.final import find_final_videos
from anigs.study.build import StudyOptions, build_study
from anigs.study.layout import Outputs as StudyOutputs
from anigs.study.serve import StudyServer
from anigs.study.tally import TallyOptions, tally, write_tally

log = logging.getLogger("anigs.study")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="study_command", metavar="ACTION", required=True)

    b = sub.add_parser("build", help="write the study folder (page, script, videos)")
    b.add_argument("--results", default="results", help="results root with {scene}/{variant}/final/{view}.mp4")
    b.add_argument("--scenes", nargs="+", required=True, help="scenes to include")
    b.add_argument("--ours", default="full", help="our variant (default: full)")
    b.add_argument("--others", nargs="+", default=None,
                   help="variants to compare with (default: every other variant with final videos)")
    b.add_argument("--out", required=True, help="study folder to write")
    b.add_argument("--seed", type=int, default=0, help="study seed (mixed with each participant id)")
    b.add_argument("--max-views", type=int, default=0, help="views per scene and comparison (0: all)")
    b.add_argument("--min-plays", type=int, default=1, help="loops both videos must play before answering")
    b.add_argument("--catch-trials", type=int, default=0,
                   help="attention checks: pairs of ours against a blurred copy of itself (not in the table)")
    b.add_argument("--post-url", default="answers", help="where the page posts answers ('none': never)")
    b.add_argument("--title", default="Video comparison study")
    b.add_argument("--label", action="append", default=[], metavar="VARIANT=LABEL",
                   help="row label of a variant in Table 4 (repeatable)")

    s = sub.add_parser("serve", help="serve a study folder on 127.0.0.1 and collect posted answers")
    s.add_argument("--dir", required=True, help="built study folder")
    s.add_argument("--answers", default=None, help="JSONL file to append to (default: the study folder's answers file)")
    s.add_argument("--port", type=int, default=8000, help="port (0: a free one)")
    s.add_argument("--seconds", type=float, default=0, help="stop after this many seconds (0: on Ctrl-C/SIGTERM)")

    t = sub.add_parser("tally", help="answer files -> Table 4 (CSV, Markdown, LaTeX)")
    t.add_argument("answers", nargs="+", help="exported .json and/or server .jsonl files")
    t.add_argument("--manifest", default=None, help="the study's manifest file (checks pairs, completeness)")
    t.add_argument("--out", required=True, help="output folder (e.g. results/tables)")
    t.add_argument("--min-time-ms", type=float, default=1000.0, help="faster answers are excluded")
    t.add_argument("--max-fast-fraction", type=float, default=0.5,
                   help="participants with a larger share of too-fast answers are excluded")
    t.add_argument("--max-catch-errors", type=int, default=0, help="attention checks a participant may fail")
    t.add_argument("--keep-incomplete", action="store_true", help="keep participants who did not finish")
    t.add_argument("--ci", choices=["wilson", "clopper-pearson"], default="wilson")
    t.add_argument("--level", type=float, default=0.95, help="confidence level of the interval")


def _labels(items: list[str]) -> dict[str, str]:
    out = {}
    for item in items:
        if "=" not in item:
            raise ValueError(f"--label wants VARIANT=LABEL, got {item!r}")
        k, v = item.split("=", 1)
        out[k] = v
    return out


def main(args: argparse.Namespace) -> int:
    return {"build": _build, "serve": _serve, "tally": _tally}[args.study_command](args)


def _build(args: argparse.Namespace) -> int:

    variants = None if args.others is None else [args.ours] + args.others
    videos = find_final_videos(args.results, args.scenes, variants)
    opts = StudyOptions(ours=args.ours, others=args.others, seed=args.seed, max_views=args.max_views,
                        min_plays=args.min_plays, catch_trials=args.catch_trials, post_url=None if args.post_url == "none" else args.post_url,
                        title=args.title, labels=_labels(args.label))
    m = build_study(videos, args.out, opts)
    log.info("study: %d pairs (%s vs %s) on %s -> %s (study id %s)", len(m["trials"]), m["ours"],
             ", ".join(m["comparisons"]), ", ".join(m["scenes"]), StudyOutputs(args.out).path("page"), m["study_id"])
    return 0


def _serve(args: argparse.Namespace) -> int:
    server = StudyServer(args.dir, args.answers, args.port)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    with server:
        print(f"anigs study: serving {args.dir} at {server.url} ; answers -> {server.store.path}", flush=True)
        try:
            stop.wait(args.seconds or None)
        except KeyboardInterrupt:
            pass
    log.info("study: server stopped; %d answers in %s", len(server.store.seen), server.store.path)
    return 0


def _tally(args: argparse.Namespace) -> int:

    opts = TallyOptions(min_time_ms=args.min_time_ms, max_fast_fraction=args.max_fast_fraction,
                        require_complete=not args.keep_incomplete, max_catch_errors=args.max_catch_errors, ci=args.ci, level=args.level)
    manifest = read_json(args.manifest) if args.manifest else None
    t, table = tally([Path(p) for p in args.answers], manifest, opts)
    paths = write_tally(t, table, args.out, opts)
    log.info("study: %d answers used, %d excluded -> %s", len(t.answers), len(t.exclusions), paths[1])
    return 0
