"""2AFC study: build from tiny fake videos, the answer server's checks, and the tally against a
hand-computed Table 4 (exclusions and interval values worked out by hand below)."""
from __future__ import annotations

import argparse
import json
import threading
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from anigs.stages.final import find_final_videos
from anigs.study.build import StudyOptions, build_study
from anigs.study.schema import ANSWER_SCHEMA, EXPORT_SCHEMA, answer_problems
from anigs.study.serve import MAX_BODY, StudyServer
from anigs.study.stats import binomial_p, clopper_pearson, cluster_bootstrap, wilson
from anigs.study.tally import TallyOptions, tally, write_tally

VARIANTS = ["full", "gs2life", "physdreamer"]


def make_videos(root: Path, scenes=("garden",), variants=VARIANTS, views=("view_000", "view_001"),
                size=(24, 32), frames=6, fps=12) -> Path:
    """results/{scene}/{variant}/final/{view}.mp4, each video different (colour per variant, phase per view)."""
    from anigs.video import write_mp4

    t = np.linspace(0, 2 * np.pi, frames, endpoint=False)[:, None, None]
    for si, scene in enumerate(scenes):
        for vi, variant in enumerate(variants):
            for wi, view in enumerate(views):
                clip = np.zeros((frames, *size, 3), np.float32)
                clip[...] = [0.15 + 0.3 * vi, 0.4 + 0.1 * si, 0.85 - 0.3 * vi]
                clip[:, size[0] // 3: 2 * size[0] // 3, :, 1] = 0.5 + 0.4 * np.sin(t + wi + np.arange(size[1]) / 4)
                write_mp4(root / scene / variant / "final" / f"{view}.mp4", clip, fps=fps)
            write_mp4(root / scene / variant / "final" / "path.mp4", clip, fps=fps)  # not a view: left out
    return root


@pytest.fixture(scope="module")
def study(tmp_path_factory) -> tuple[Path, dict]:
    tmp = tmp_path_factory.mktemp("study")
    videos = find_final_videos(make_videos(tmp / "results"), ["garden"])
    return tmp / "study", build_study(videos, tmp / "study", StudyOptions(seed=3))


# ----------------------------------------------------------------------------- build

def test_build_pairs_ours_with_every_other_variant_per_view(study):
    out, m = study
    assert sorted(t["id"] for t in m["trials"]) == sorted(
        f"garden/{v}/{o}" for v in ("view_000", "view_001") for o in ("gs2life", "physdreamer"))
    assert m["comparisons"] == ["gs2life", "physdreamer"] and m["ours"] == "full"
    names = {p for t in m["trials"] for p in t["videos"].values()}
    assert len(names) == 6  # 3 variants x 2 views, each copied once, path.mp4 left out
    for name in names:
        assert (out / name).is_file() and not any(v in name for v in VARIANTS)  # names do not reveal the method
    for t in m["trials"]:
        assert set(t["videos"]) == {"full", t["other"]} and t["size"] == [32, 24]
    inline = (out / "index.html").read_text().split('type="application/json">')[1].split("</script>")[0]
    assert json.loads(inline) == json.loads((out / "manifest.json").read_text()) == m
    assert (out / "study.js").is_file() and (out / "study.css").is_file()
    assert [q["id"] for q in m["questions"]] == ["motion", "quality"]


def test_build_is_reproducible_and_removes_stale_videos(study, tmp_path):
    out, m = study
    videos = find_final_videos(out.parent / "results", ["garden"])
    again = build_study(videos, tmp_path / "s", StudyOptions(seed=3))
    assert again["study_id"] == m["study_id"]
    assert build_study(videos, tmp_path / "s2", StudyOptions(seed=4))["study_id"] != m["study_id"]
    (tmp_path / "s" / "videos" / "old.mp4").write_bytes(b"x")
    one = build_study(videos, tmp_path / "s", StudyOptions(seed=3, others=["gs2life"], max_views=1))
    assert len(one["trials"]) == 1 and one["comparisons"] == ["gs2life"]
    assert sorted(p.name for p in (tmp_path / "s" / "videos").iterdir()) == sorted(
        Path(p).name for p in one["trials"][0]["videos"].values())


def test_build_refuses_unmatched_or_missing_videos(tmp_path):
    root = make_videos(tmp_path / "r", variants=["full"])
    make_videos(tmp_path / "r", variants=["other"], size=(16, 32))
    with pytest.raises(ValueError, match="same size"):
        build_study(find_final_videos(root, ["garden"]), tmp_path / "s")
    with pytest.raises(ValueError, match="no videos of ours"):
        build_study(find_final_videos(root, ["garden"]), tmp_path / "s", StudyOptions(ours="nope"))
    with pytest.raises(FileNotFoundError, match="no camera-fixed videos"):
        find_final_videos(root, ["garden"], ["full", "missing"])
    with pytest.raises(ValueError, match="nothing to compare|no variant to compare"):
        build_study(find_final_videos(root, ["garden"], ["full"]), tmp_path / "s")


# ----------------------------------------------------------------------------- server

def answer(m: dict, pid: str, trial: dict, q: str, ours_chosen: bool, pos: int = 0, ms: float = 2000.0,
           left_ours: bool = True, at: str = "2026-11-23T12:00:00.000Z") -> dict:
    left = trial["ours"] if left_ours else trial["other"]
    chosen = trial["ours"] if ours_chosen else trial["other"]
    return {"schema": ANSWER_SCHEMA, "study_id": m["study_id"], "participant": pid, "pair": trial["id"],
            "scene": trial["scene"], "view": trial["view"], "ours": trial["ours"], "other": trial["other"],
            "question": q, "left": left, "side": "left" if chosen == left else "right", "chosen": chosen,
            "time_ms": ms, "trial": pos, "n_trials": len(m["trials"]), "answered_at": at}


def post(url: str, body: bytes, ctype: str = "application/json") -> tuple[int, dict]:
    req = urllib.request.Request(url + "answers", data=body, method="POST", headers={"Content-Type": ctype})
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def test_server_rejects_malformed_posts_and_appends_valid_ones(study, tmp_path):
    out, m = study
    good = answer(m, "p1", m["trials"][0], "motion", True)
    bad_side = {**good, "side": "right"}  # contradicts chosen/left
    with StudyServer(out, tmp_path / "a.jsonl") as s:
        cases = [
            (b"{not json", "application/json", "not valid UTF-8 JSON"),
            (json.dumps(good).encode(), "text/plain", "Content-Type must be application/json"),
            (json.dumps({k: v for k, v in good.items() if k != "question"}).encode(), "application/json",
             "missing fields ['question']"),
            (json.dumps(bad_side).encode(), "application/json", "contradicts side"),
            (json.dumps({**good, "pair": "garden/x/gs2life"}).encode(), "application/json", "not in this study"),
            (json.dumps({**good, "study_id": "other"}).encode(), "application/json", "is not this study"),
            (json.dumps({**good, "time_ms": -1}).encode(), "application/json", "'time_ms' must be"),
            (json.dumps([good]).encode(), "application/json", "expected an answer object"),
            (json.dumps({"answers": [good, bad_side]}).encode(), "application/json", "answer 1:"),
        ]
        for body, ctype, msg in cases:
            code, reply = post(s.url, body, ctype)
            assert code == 400 and msg in reply["error"], (msg, code, reply)
        code, reply = post(s.url, b"x" * (MAX_BODY + 1))
        assert code == 413
        assert not (tmp_path / "a.jsonl").exists()  # nothing malformed was stored, not even half a batch
        assert post(s.url, json.dumps(good).encode()) == (200, {"stored": 1, "duplicates": 0})
        assert post(s.url, json.dumps({"answers": [good]}).encode()) == (200, {"stored": 0, "duplicates": 1})
        with urllib.request.urlopen(s.url + "index.html", timeout=10) as r:
            assert r.status == 200 and m["study_id"] in r.read().decode()
        for private in ("answers.jsonl", "manifest.json", "videos/../answers.jsonl"):
            with pytest.raises(urllib.error.HTTPError, match="404"):
                urllib.request.urlopen(s.url + private, timeout=10)
        video = m["trials"][0]["videos"]["full"]
        req = urllib.request.Request(s.url + video, headers={"Range": "bytes=10-19"})
        with urllib.request.urlopen(req, timeout=10) as r:
            assert r.status == 206 and r.read() == (out / video).read_bytes()[10:20]
    lines = (tmp_path / "a.jsonl").read_text().splitlines()
    assert len(lines) == 1 and {k: v for k, v in json.loads(lines[0]).items() if k != "received_at"} == good


def test_server_appends_concurrent_posts_whole(study, tmp_path):
    out, m = study
    pids = [f"c{i}" for i in range(8)]
    with StudyServer(out, tmp_path / "a.jsonl") as s:
        def send(pid: str) -> None:
            batch = [answer(m, pid, t, q, True, i) for i, t in enumerate(m["trials"]) for q in ("motion", "quality")]
            assert post(s.url, json.dumps({"answers": batch}).encode())[0] == 200
        threads = [threading.Thread(target=send, args=(p,)) for p in pids]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
    rows = [json.loads(x) for x in (tmp_path / "a.jsonl").read_text().splitlines()]
    assert len(rows) == 8 * len(m["trials"]) * 2 and all(not answer_problems(r) for r in rows)


# ----------------------------------------------------------------------------- statistics

def test_intervals_match_hand_computed_values():
    # Wilson, z = 1.959964: 3/4 -> centre (0.75 + z^2/8)/(1 + z^2/4) = 0.627527, half-width 0.326886
    assert wilson(3, 4) == pytest.approx((0.300642, 0.954413), abs=1e-6)
    assert wilson(0, 10) == pytest.approx((0.0, 3.841459 / 13.841459), abs=1e-6)  # z^2 / (n + z^2)
    assert clopper_pearson(0, 10) == pytest.approx((0.0, 1 - 0.025 ** 0.1), abs=1e-9)
    assert clopper_pearson(10, 10) == pytest.approx((0.025 ** 0.1, 1.0), abs=1e-9)
    assert binomial_p(9, 10) == pytest.approx(22 / 1024)  # 2 * (C(10,9) + C(10,10)) / 2^10
    with pytest.raises(ValueError):
        wilson(5, 4)
    # resampling whole participants: one always for ours, one always against -> anything from 0 to 1,
    # where the answer-level Wilson interval of the same 2/4 is much narrower
    assert cluster_bootstrap([2, 0], [2, 2]) == (0.0, 1.0) and wilson(2, 4)[1] - wilson(2, 4)[0] < 0.85
    assert cluster_bootstrap([2, 3], [2, 3]) == (1.0, 1.0)


# ----------------------------------------------------------------------------- tally

def hand_study(study) -> tuple[dict, list[dict], list[dict], list[str]]:
    """Answers of four participants + faults; the expected table is worked out in the test."""
    _, m = study
    tr = {(t["view"], t["other"]): t for t in m["trials"]}
    order = [("view_000", "gs2life"), ("view_001", "gs2life"), ("view_000", "physdreamer"), ("view_001", "physdreamer")]

    def full(pid: str, other_wins: set, fast: set) -> list[dict]:
        out = []
        for i, key in enumerate(order):
            for q in ("motion", "quality"):
                out.append(answer(m, pid, tr[key], q, (key, q) not in other_wins, i,
                                  300.0 if (key, q) in fast else 2500.0, left_ours=i % 2 == 0,
                                  at=f"2026-11-23T12:0{i}:00.000Z"))
        return out

    a = full("A", {(order[3], "quality")}, set())
    b = full("B", {(order[0], "quality")}, {(order[2], "motion")})  # one too-fast answer: only it goes
    c = full("C", set(), set())[:6]  # stopped after three pairs: incomplete
    d = full("D", set(), {(k, q) for k in order[:3] for q in ("motion",)} | {(order[0], "quality"),
                                                                             (order[1], "quality")})  # 5 of 8 fast
    redo = {**a[0], "chosen": a[0]["other"], "side": "right" if a[0]["side"] == "left" else "left",
            "answered_at": "2026-11-23T13:00:00.000Z"}  # A answers pair 1 again later: the first counts
    foreign = {**a[1], "study_id": "0000deadbeef"}
    contradict = {**b[1], "side": "right" if b[1]["side"] == "left" else "left"}
    jsonl = a + [redo, foreign, contradict] + c + d
    export = {"schema": EXPORT_SCHEMA, "study_id": m["study_id"], "participant": "B", "answers": b + [b[3]]}
    return m, jsonl, [export], ["{broken line"]


def test_tally_reproduces_a_hand_computed_table(study, tmp_path):
    m, jsonl, exports, broken = hand_study(study)
    (tmp_path / "server.jsonl").write_text("\n".join([json.dumps(x) for x in jsonl] + broken) + "\n")
    (tmp_path / "B.json").write_text(json.dumps(exports[0]))
    opts = TallyOptions(min_time_ms=1000)
    t, table = tally([tmp_path / "server.jsonl", tmp_path / "B.json"], m, opts)
    reasons = {}
    for e in t.exclusions:
        reasons[e.reason] = reasons.get(e.reason, 0) + 1
    # malformed: the broken line + the contradicting answer; other study: 1; duplicates: A's redo + B's copy;
    # incomplete: C's 6; careless: D's 8 (5 of 8 too fast > 50%); too fast: B's one
    assert reasons == {"malformed": 2, "other_study": 1, "duplicate": 2, "incomplete": 6, "careless": 8, "too_fast": 1}
    assert len(t.answers) == 8 + 7 and sorted({a["participant"] for a in t.answers}) == ["A", "B"]
    assert len(t.participants_seen) == 4
    rows = {(r["question"], r["other"]): r for r in t.rows}
    # motion vs gs2life: A 2/2 + B 2/2; motion vs physdreamer: A 2/2 + B 1/1 (one too fast)
    # quality vs gs2life: A 2/2 + B 1/2; quality vs physdreamer: A 1/2 + B 2/2
    assert [(rows[k]["prefer_ours"], rows[k]["answers"]) for k in
            [("motion", "gs2life"), ("motion", "physdreamer"), ("quality", "gs2life"), ("quality", "physdreamer")]] \
        == [(4, 4), (3, 3), (3, 4), (3, 4)]
    # Wilson n/n: centre and half-width add up to 1, lower bound = n / (n + z^2), z^2 = 3.841459
    assert (rows[("motion", "gs2life")]["ci_low"], rows[("motion", "gs2life")]["ci_high"]) == pytest.approx(
        (4 / 7.841459, 1.0), abs=1e-6)
    assert rows[("motion", "physdreamer")]["ci_low"] == pytest.approx(3 / 6.841459, abs=1e-6)
    assert (rows[("quality", "gs2life")]["ci_low"], rows[("quality", "gs2life")]["ci_high"]) == pytest.approx((0.300642, 0.954413), abs=1e-6)
    assert rows[("quality", "physdreamer")]["participants"] == 2
    paths = write_tally(t, table, tmp_path / "tables", opts)
    md = (tmp_path / "tables" / "table4_user_study.md").read_text()
    assert "| Ours vs gs2life | **100.0 [51.0, 100.0] n=4** |" in md  # bold: the interval excludes 50%
    assert "| Ours vs physdreamer | 100.0 [43.9, 100.0] n=3 |" in md
    assert md.count("75.0 [30.1, 95.4] n=4") == 2 and "**Motion realism**" in md and "**Visual quality**" in md
    assert "2 participants and 15 answers used; 2 participants and 20 answers excluded" in md
    # left chosen: A 5 of 8 (ours on the left in pairs 1 and 3), B 2 of 7 -> 7/15
    assert "the left video was chosen in 46.7% of the answers" in md
    people = {x.split(",")[0]: x for x in (tmp_path / "tables" / "table4_participants.csv").read_text().splitlines()}
    assert people["A"].startswith("A,10,8,duplicate:1 other_study:1,")
    assert people["B"].startswith("B,10,7,duplicate:1 malformed:1 too_fast:1,") and people["D"].startswith("D,8,0,careless:8,")
    long_rows = {(r["question"], r["other"]): r for r in t.rows}
    assert long_rows[("motion", "gs2life")]["cluster_ci_low"] == 1.0  # both participants always chose ours
    tex = (tmp_path / "tables" / "table4_user_study.tex").read_text()
    assert r"\textbf{100.0 [51.0, 100.0] n=4}" in tex and r"in \%" in tex
    excl = (tmp_path / "tables" / "table4_exclusions.csv").read_text()
    assert "incomplete,participant answered 6 of 8" in excl and "answered again after server.jsonl:1" in excl
    assert all(p.exists() for p in paths)


def test_tally_options_change_the_result(study, tmp_path):
    m, jsonl, exports, _ = hand_study(study)
    (tmp_path / "s.jsonl").write_text("\n".join(json.dumps(x) for x in jsonl) + "\n")
    (tmp_path / "B.json").write_text(json.dumps(exports[0]))
    files = [tmp_path / "s.jsonl", tmp_path / "B.json"]
    t, _ = tally(files, m, TallyOptions(min_time_ms=0, require_complete=False))
    assert {a["participant"] for a in t.answers} == {"A", "B", "C", "D"} and len(t.answers) == 8 + 8 + 6 + 8
    t, _ = tally(files, m, TallyOptions(ci="clopper-pearson"))
    q = next(r for r in t.rows if r["question"] == "quality" and r["other"] == "gs2life")
    assert (q["ci_low"], q["ci_high"]) == pytest.approx((0.194120, 0.993691), abs=1e-6)
    with pytest.raises(ValueError, match="several studies"):
        tally(files, None)
    with pytest.raises(ValueError, match="unknown interval"):
        tally(files, m, TallyOptions(ci="normal"))


def test_cli_build_then_tally(tmp_path):
    from anigs.stages.study import add_arguments, main

    make_videos(tmp_path / "results", scenes=("garden", "trail"), variants=["full", "g2l"], views=("v0",))
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    assert main(parser.parse_args(["build", "--results", str(tmp_path / "results"), "--scenes", "garden", "trail",
                                  "--out", str(tmp_path / "study"), "--label", "g2l=Gaussians2Life"])) == 0
    m = json.loads((tmp_path / "study" / "manifest.json").read_text())
    ans = [answer(m, "P", t, q, t["scene"] == "garden", i) for i, t in enumerate(m["trials"]) for q in ("motion", "quality")]
    (tmp_path / "a.jsonl").write_text("\n".join(json.dumps(a) for a in ans) + "\n")
    assert main(parser.parse_args(["tally", str(tmp_path / "a.jsonl"), "--manifest", str(tmp_path / "study" / "manifest.json"),
                                  "--out", str(tmp_path / "tables")])) == 0
    import csv

    rows = list(csv.reader((tmp_path / "tables" / "table4_user_study.csv").open()))
    assert rows[0] == ["block", "Preference for ours", "garden", "trail", "All"]
    # Wilson 1/1: [1/(1+z^2), 1]; 0/1: [0, z^2/(1+z^2)]; 1/2: 0.5 -+ z*sqrt(1/8 + z^2/16)/(1 + z^2/2) = 0.5 -+ 0.4055
    assert rows[1] == ["Motion realism", "Ours vs Gaussians2Life", "100.0 [20.7, 100.0] n=1", "0.0 [0.0, 79.3] n=1",
                       "50.0 [9.5, 90.5] n=2"]


def test_attention_checks_exclude_participants_who_prefer_the_blurred_copy(tmp_path):
    from anigs.video import read_mp4

    videos = find_final_videos(make_videos(tmp_path / "r", variants=["full", "gs2life"], views=("v0", "v1")), ["garden"])
    m = build_study(videos, tmp_path / "s", StudyOptions(catch_trials=1, seed=5))
    catch = [t for t in m["trials"] if t.get("catch")]
    assert len(catch) == 1 and m["catch_trials"] == 1 and m["comparisons"] == ["gs2life"]
    sharp, blurred = (read_mp4(tmp_path / "s" / catch[0]["videos"][v]) for v in ("full", "catch"))
    assert sharp.shape == blurred.shape
    def edges(c: np.ndarray) -> float:  # gradient energy (blur keeps the total variation of a step, not this)
        return float((np.diff(c, axis=1) ** 2).mean() + (np.diff(c, axis=2) ** 2).mean())

    assert edges(blurred) < 0.6 * edges(sharp)
    assert not list((tmp_path / "s").glob(".*.mp4"))  # the temporary blurred file is gone

    def participant(pid: str, fooled: bool) -> list[dict]:
        out = []
        for i, t in enumerate(m["trials"]):
            for q in ("motion", "quality"):
                out.append(answer(m, pid, t, q, not (t.get("catch") and fooled and q == "quality"), i))
        return out

    (tmp_path / "a.jsonl").write_text("\n".join(json.dumps(a) for a in participant("ok", False) + participant("no", True)))
    t, table = tally([tmp_path / "a.jsonl"], m)
    assert {a["participant"] for a in t.answers} == {"ok"} and len(t.answers) == 4 and len(t.catch) == 2
    assert [e.reason for e in t.exclusions] == ["failed_catch"] * 6
    assert [(r["other"], r["answers"]) for r in t.rows] == [("gs2life", 2), ("gs2life", 2)]  # catch not in the table
    assert any("1 participant passed, 1 failed and excluded" in f for f in table.footnotes)
    t, _ = tally([tmp_path / "a.jsonl"], m, TallyOptions(max_catch_errors=1))
    assert {a["participant"] for a in t.answers} == {"ok", "no"}


def test_serve_command_runs_on_a_free_port_and_stops_on_sigterm(study, tmp_path):
    import signal
    import subprocess
    import sys

    out, m = study
    code = ("import argparse, sys; from anigs.stages import study as cli; p = argparse.ArgumentParser(); "
            "cli.add_arguments(p); sys.exit(cli.main(p.parse_args(sys.argv[1:])))")
    proc = subprocess.Popen([sys.executable, "-c", code, "serve", "--dir", str(out), "--port", "0", "--answers",
                             str(tmp_path / "a.jsonl"), "--seconds", "120"], stdout=subprocess.PIPE, text=True,
                            cwd=Path(__file__).resolve().parents[2])
    try:
        line = proc.stdout.readline()
        url = line.split(" at ")[1].split(" ")[0]
        assert url.startswith("http://127.0.0.1:")
        assert post(url, json.dumps(answer(m, "cli", m["trials"][0], "motion", True)).encode())[0] == 200
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=20) == 0
    finally:
        proc.kill()
    assert len((tmp_path / "a.jsonl").read_text().splitlines()) == 1
