"""The study page in a real headless Chromium (Debian's chromium + chromium-driver, Selenium from PyPI).

A participant answers every pair by a fixed policy (decided from the videos actually shown on each
side, not from what the page says about them), reloads the page halfway and once more in the middle
of a pair, finishes, downloads the answers; the posted JSONL and the downloaded file must both tally
into the table the policy implies. Skipped only when the browser, the driver or Selenium is missing.
"""
from __future__ import annotations

import json
from pathlib import Path


from anigs.stages.final import find_final_videos
from anigs.study.build import StudyOptions, build_study
from anigs.study.serve import StudyServer
from anigs.study.tally import TallyOptions, tally
from tests._browser import chrome as _chrome, needs_browser
from tests.study.test_study import make_videos

pytestmark = needs_browser


def chrome(download_dir: Path):
    return _chrome((1280, 860), download_dir=download_dir)


def policy(trial: dict, question: str) -> str:
    """The variant the simulated participant prefers: ours, except in three cells of the table."""
    if (trial["scene"], trial["other"], question) in {("garden", "gs2life", "quality"), ("trail", "physdreamer", "motion"),
                                                      ("trail", "gs2life", "quality")}:
        return trial["other"]
    return trial["ours"]


def expected_rows(manifest: dict) -> dict[tuple[str, str, str], tuple[int, int]]:
    out: dict[tuple[str, str, str], tuple[int, int]] = {}
    for t in manifest["trials"]:
        for q in ("motion", "quality"):
            for scene in (t["scene"], "All"):
                k, n = out.get((q, t["other"], scene), (0, 0))
                out[(q, t["other"], scene)] = (k + (policy(t, q) == t["ours"]), n + 1)
    return out


def test_participant_answers_every_pair_with_reloads_and_the_answers_tally(tmp_path):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    videos = find_final_videos(make_videos(tmp_path / "results", scenes=("garden", "trail"), views=("v0",)),
                               ["garden", "trail"])
    m = build_study(videos, tmp_path / "study", StudyOptions(seed=7, min_plays=1))
    n = len(m["trials"])
    assert n == 4
    by_videos = {frozenset(t["videos"].values()): t for t in m["trials"]}
    (tmp_path / "dl").mkdir()
    seen: list[tuple[str, str]] = []  # (pair, variant shown on the left), from the <video> elements

    with StudyServer(tmp_path / "study", tmp_path / "answers.jsonl") as server:
        d = chrome(tmp_path / "dl")
        wait = WebDriverWait(d, 30)
        try:
            d.get(server.url + "index.html?participant=browser-1")
            assert d.find_element(By.ID, "n-pairs").text == str(n)
            d.find_element(By.ID, "start").click()

            def answer(q: str, trial: dict, left: str, right: str) -> None:
                chosen = policy(trial, q)
                d.find_element(By.ID, f"q-{q}-{'left' if chosen == left else 'right'}").click()

            for pos in range(n):
                wait.until(lambda d: d.find_element(By.ID, "q-motion-left").is_enabled())
                assert d.find_element(By.ID, "progress").text == f"Pair {pos + 1} of {n}"
                srcs = [d.find_element(By.ID, f"video-{s}").get_dom_attribute("src") for s in ("left", "right")]
                trial = by_videos[frozenset(srcs)]
                left, right = (v for s in srcs for v, p in trial["videos"].items() if p == s)
                decoded = d.execute_script("return [0, 1].map(i => [document.querySelectorAll('video')[i].videoWidth,"
                                           " document.querySelectorAll('video')[i].readyState])")
                assert [w for w, _ in decoded] == [32, 32] and all(r >= 2 for _, r in decoded)  # decoded, playing
                seen.append((trial["id"], left))
                assert d.find_element(By.ID, "next").is_enabled() is False
                answer("motion", trial, left, right)
                if pos == 2:  # reload in the middle of a pair: the draft answer survives
                    d.refresh()
                    wait.until(lambda d: d.find_element(By.ID, "q-motion-left").is_enabled())
                    assert d.find_element(By.ID, "progress").text == f"Pair 3 of {n}"
                    side = "left" if policy(trial, "motion") == left else "right"
                    assert "selected" in d.find_element(By.ID, f"q-motion-{side}").get_attribute("class")
                answer("quality", trial, left, right)
                d.find_element(By.ID, "next").click()
                if pos == 1:  # reload halfway: nothing is lost, the page resumes at pair 3
                    d.refresh()
                    wait.until(lambda d: d.find_element(By.ID, "progress").text == f"Pair 3 of {n}")
                    assert len(d.execute_script("return window.anigsStudy.state().answers")) == 4
            wait.until(lambda d: d.find_element(By.ID, "done").is_displayed())
            wait.until(lambda d: f"sent to the server: {2 * n} of {2 * n}" in d.find_element(By.ID, "save-status").text)
            d.save_screenshot(str(tmp_path / "done.png"))
            d.find_element(By.ID, "download-done").click()
            wait.until(lambda d: list((tmp_path / "dl").glob("anigs-study-*.json")))
        finally:
            d.quit()

    # the page showed every pair once, ours on the left in exactly half of them (counterbalanced)
    assert sorted(p for p, _ in seen) == sorted(t["id"] for t in m["trials"])
    assert sum(left == "full" for _, left in seen) == n // 2
    exported = next((tmp_path / "dl").glob("anigs-study-*.json"))
    data = json.loads(exported.read_text())
    assert data["complete"] and data["participant"] == "browser-1" and len(data["answers"]) == 2 * n
    assert {(a["pair"], a["left"]) for a in data["answers"]} == set(seen)  # recorded sides = shown sides
    # pair 3 was on screen when the page reloaded (its timer restarted): flagged; pair 1 was not
    assert [a["reloaded"] for a in data["answers"] if a["trial"] in (0, 2)] == [False, False, True, True]
    posted = [json.loads(x) for x in (tmp_path / "answers.jsonl").read_text().splitlines()]
    assert len(posted) == 2 * n

    want = expected_rows(m)
    for files in ([tmp_path / "answers.jsonl"], [exported]):
        t, table = tally(files, m, TallyOptions(min_time_ms=0))
        assert not t.exclusions and len(t.answers) == 2 * n
        got = {(r["question"], r["other"], r["scene"]): (r["prefer_ours"], r["answers"]) for r in t.rows}
        assert got == want


def test_page_works_from_the_file_system_without_a_server(tmp_path):
    """Opened as file://: videos play, answers are kept in the browser, nothing is posted."""
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    videos = find_final_videos(make_videos(tmp_path / "results", variants=["full", "gs2life"], views=("v0",)),
                               ["garden"])
    m = build_study(videos, tmp_path / "study", StudyOptions(min_plays=1))
    d = chrome(tmp_path)
    try:
        d.get((tmp_path / "study" / "index.html").as_uri())
        pid = d.find_element(By.ID, "participant-intro").text
        assert pid.startswith("p-") and len(pid) == 14  # anonymous random id
        d.find_element(By.ID, "start").click()
        WebDriverWait(d, 30).until(lambda d: d.find_element(By.ID, "q-motion-right").is_enabled())
        d.find_element(By.ID, "q-motion-right").click()
        d.find_element(By.ID, "q-quality-left").click()
        d.find_element(By.ID, "next").click()
        WebDriverWait(d, 10).until(lambda d: d.find_element(By.ID, "done").is_displayed())
        status = d.find_element(By.ID, "save-status").text
        assert status == "2 answers saved in this browser." and d.find_element(By.ID, "error").is_displayed() is False
        data = d.execute_script("return window.anigsStudy.exportData()")
        d.refresh()  # the same participant comes back, finished
        assert d.find_element(By.ID, "participant-footer").text == pid
        assert WebDriverWait(d, 10).until(lambda d: d.find_element(By.ID, "done").is_displayed())
    finally:
        d.quit()
    assert data["study_id"] == m["study_id"] and [a["side"] for a in data["answers"]] == ["right", "left"]
