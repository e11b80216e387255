"""The WebGL2 viewer in a real headless Chromium (Debian's chromium + chromium-driver, Selenium).

WebGL runs on SwiftShader, Chromium's software renderer. Frames are read back from the canvas
and compared with ``anigs.render`` at the same camera and time. Skipped only when chromium,
chromedriver or selenium is missing; with ANIGS_REQUIRE_BROWSER=1 (CI) a missing one is an error.
"""
from __future__ import annotations

import base64
import math

import numpy as np
import pytest
import torch

from anigs.synth.scene import SKY
from tests._browser import chrome, needs_browser
from tests.viewer.test_viewer_compact import _views_json, animated_scene

pytestmark = needs_browser

BACKGROUND = list(SKY)
TIMES = (0.0, 2.5, 8.0)


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """A small animated scene (SH degree 3, rotation, smooth limits) in a served viewer folder."""
    from anigs.stages.view import Outputs as ViewOutputs
    from anigs.viewer.build import build_viewer
    from anigs.viewer.compact import load_compact, save_compact
    from anigs.viewer.serve import start_server

    tmp = tmp_path_factory.mktemp("viewer")
    canonical, deformation = animated_scene(n=1500, d=300, T=9, K=4, sh_degree=3, limits=True, seed=3,
                                            scale_range=(0.01, 0.15))
    save_compact(tmp / "scene.anigs", canonical, deformation)
    views = _views_json(tmp / "views.json")
    build_viewer(tmp / "scene.anigs", ViewOutputs(tmp / "viewer"), views, background=BACKGROUND)
    server = start_server(ViewOutputs(tmp / "viewer"))
    yield {"dir": tmp / "viewer", "url": server.url, "scene": load_compact(tmp / "scene.anigs"), "views": views}
    server.stop()


@pytest.fixture(scope="module")
def browser():
    driver = chrome((900, 600), webgl=True)
    driver.set_script_timeout(60)
    yield driver
    driver.quit()


def _open(driver, url: str) -> dict:
    driver.get(url + "?scale=1&paused=1")
    info = driver.execute_async_script(
        "const done = arguments[0]; window.anigsViewer.ready.then(v => done(v.info()), e => done('ERROR ' + e));")
    assert isinstance(info, dict), info
    return info


def _frame(driver, view: int, t: float, shape: tuple[int, int]) -> np.ndarray:
    """The canvas [H,W,3] in [0,1] after drawing view ``view`` at time t with its own depth order."""
    b64 = driver.execute_async_script(
        "const [view, t, done] = arguments; const v = window.anigsViewer; v.setView(view); v.setTime(t);"
        "v.renderExact().then(() => done(v.pixelsBase64()));", view, t)
    px = np.frombuffer(base64.b64decode(b64), np.uint8).reshape(shape[0], shape[1], 4)
    return px[..., :3].astype(np.float64) / 255.0


def _reference(scene, camera, t: float) -> np.ndarray:
    from anigs.render import render_gaussians

    with torch.no_grad():
        rgb, _, _ = render_gaussians(scene.frame(t), camera, background=torch.tensor(BACKGROUND))
    return rgb.clamp(0, 1).numpy().astype(np.float64)


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    return 10 * math.log10(1.0 / max(float(((a - b) ** 2).mean()), 1e-12))


def test_viewer_matches_rasterizer(site, browser):
    """Canvas vs anigs.render at 2 views x 3 times (incl. fractional). The issue's target is 30 dB on
    the demo; here the viewer reaches the 8-bit readback limit (~59 dB), and 50 dB still catches a
    10 % footprint error or the rotation offset composed on the wrong side (40-44 dB)."""
    import json

    from anigs.views import cameras_from_views

    info = _open(browser, site["url"])
    assert info["num_gaussians"] == 1500 and info["num_dynamic"] == 300 and info["playing"] is False
    cams = cameras_from_views(json.loads(site["views"].read_text()))
    assert (info["width"], info["height"]) == (cams[0].width, cams[0].height)  # starts at the first view
    for view, cam in enumerate(cams):
        for t in TIMES:
            ours = _frame(browser, view, t, (cam.height, cam.width))
            ref = _reference(site["scene"], cam, t)
            assert _psnr(ours, ref) >= 50.0, f"view {view} t {t}: {_psnr(ours, ref):.2f} dB"
            assert ours.std() > 0.05  # a scene, not a blank canvas


def test_static_pixels_stay_still_and_moving_ones_move(site, browser):
    """Pixels no dynamic Gaussian reaches (at either time, 2 px margin) are byte-identical between times."""
    import json

    from scipy.ndimage import binary_dilation

    from anigs.render import render_gaussians
    from anigs.views import cameras_from_views

    _open(browser, site["url"])
    scene = site["scene"]
    cam = cameras_from_views(json.loads(site["views"].read_text()))[0]
    a, b = _frame(browser, 0, 0.0, (cam.height, cam.width)), _frame(browser, 0, 5.5, (cam.height, cam.width))
    idx = scene.deformation.dynamic_index
    touched = np.zeros((cam.height, cam.width), bool)
    for t in (0.0, 5.5):
        with torch.no_grad():
            _, alpha, _ = render_gaussians(scene.frame(t).subset(idx), cam)
        touched |= alpha.numpy() > 0
    still = ~binary_dilation(touched, iterations=2)
    assert still.mean() > 0.2 and touched.mean() > 0.05
    assert np.array_equal(a[still], b[still])
    changed = np.abs(a - b).max(-1) > 2 / 255
    assert changed[touched].mean() > 0.1  # the motion is evaluated in the shader


def test_controls_play_scrub_toggle_orbit_fly(site, browser):
    import time

    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    _open(browser, site["url"])
    viewer_t = lambda: browser.execute_script("return window.anigsViewer.info().t")
    browser.find_element(By.ID, "play").click()  # play
    t0 = viewer_t()
    deadline = time.time() + 20
    while viewer_t() == t0 and time.time() < deadline:
        time.sleep(0.1)
    assert viewer_t() != t0 and browser.execute_script("return window.anigsViewer.playing")
    # scrubbing the slider pauses and sets the time
    browser.execute_script("const s = document.getElementById('time'); s.value = '3.5';"
                           "s.dispatchEvent(new Event('input'));")
    assert browser.execute_script("return window.anigsViewer.playing") is False
    assert viewer_t() == pytest.approx(3.5)
    plain = _frame(browser, 0, 3.5, (72, 96))
    browser.find_element(By.ID, "moving").click()
    tinted = _frame(browser, 0, 3.5, (72, 96))
    assert np.abs(plain - tinted).max() > 0.2  # moving regions are tinted
    browser.find_element(By.ID, "moving").click()
    assert np.array_equal(_frame(browser, 0, 3.5, (72, 96)), plain)
    # orbit with the mouse, fly with W, then R goes back to the view's camera
    camera = lambda: browser.execute_script("const c = window.anigsViewer.camera; return c.pos.concat(c.fwd)")
    start = camera()
    canvas = browser.find_element(By.ID, "canvas")
    ActionChains(browser).drag_and_drop_by_offset(canvas, 30, 10).perform()
    orbited = camera()
    assert not np.allclose(orbited, start)
    moved = browser.execute_async_script("const d = arguments[0], v = window.anigsViewer;"
                                         "v.renderExact().then(() => d(v.pixelsBase64()));")
    assert moved != base64.b64encode((plain * 255).round().astype(np.uint8)).decode()
    ActionChains(browser).key_down("w").pause(0.5).key_up("w").perform()
    flown = camera()
    assert np.dot(np.subtract(flown[:3], orbited[:3]), orbited[3:]) > 0  # moved forward
    ActionChains(browser).send_keys("r").perform()
    assert np.allclose(camera(), start)
    browser.execute_script("window.anigsViewer.setTime(3.5)")
    assert np.array_equal(_frame(browser, 0, 3.5, (72, 96)), plain)


def test_opens_from_the_file_system(site, browser):
    """index.html opened as file:// (no server): the embedded scene.js and a Blob worker."""
    _open(browser, site["url"])
    served = _frame(browser, 1, 4.0, (72, 96))
    _open(browser, (site["dir"] / "index.html").as_uri())
    assert browser.execute_script("return location.protocol") == "file:"
    assert np.array_equal(_frame(browser, 1, 4.0, (72, 96)), served)
