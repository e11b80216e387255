"""``canonical.glb`` (KHR_gaussian_splatting) in the PlayCanvas engine's own glTF reader and gsplat
renderer (npm ``playcanvas``, pinned in ``envs/npm/package.json``), in headless Chromium: with no
rotation of ours (the file's node stands anigs's +z-up scene +y up), a level camera sees what anigs's
rasterizer sees from the same place (README.md, "Opening the exports in other tools")."""
from __future__ import annotations

import base64
import io
import json
import math

import numpy as np

from anigs.formats.orientation import Y_UP
from tests._browser import chrome, needs_browser
from tests._node import needs_node
from tests.viewer.test_spark_browser import _level_camera, _reference, site  # noqa: F401 (fixture)

pytestmark = [needs_browser, needs_node("playcanvas")]

SCRIPT = """
const [o, done] = arguments;
(async () => {
  const pc = await import("./node_modules/playcanvas/build/playcanvas.mjs");
  const canvas = document.createElement("canvas");
  canvas.width = o.width; canvas.height = o.height;
  document.body.appendChild(canvas);
  const app = new pc.Application(canvas, { graphicsDeviceOptions: { preserveDrawingBuffer: true, antialias: false,
                                                                    deviceTypes: ["webgl2"] } });
  app.setCanvasFillMode(pc.FILLMODE_NONE);
  app.setCanvasResolution(pc.RESOLUTION_FIXED, o.width, o.height);
  app.start();
  const asset = new pc.Asset("scene", "container", { url: o.url });
  await new Promise((resolve, reject) => { asset.ready(resolve); asset.on("error", reject);
                                           app.assets.add(asset); app.assets.load(asset); });
  const entity = asset.resource.instantiateRenderEntity();
  app.root.addChild(entity);
  const camera = new pc.Entity("camera");
  camera.addComponent("camera", { clearColor: new pc.Color(0, 0, 0, 1), fov: o.fovY, nearClip: 0.01, farClip: 1000,
                                  gammaCorrection: pc.GAMMA_SRGB, toneMapping: pc.TONEMAP_NONE });
  app.root.addChild(camera);
  camera.setPosition(o.eye[0], o.eye[1], o.eye[2]);
  camera.lookAt(o.target[0], o.target[1], o.target[2]);  // +y up: a level camera
  for (let i = 0; i < 40; i++) await new Promise(r => requestAnimationFrame(r));
  const url = canvas.toDataURL("image/png");
  app.destroy();
  return url;
})().then(done, e => done("ERROR " + e + " " + (e && e.stack)));
"""


def test_playcanvas_reads_canonical_glb_upright(site, tmp_path):  # noqa: F811
    import imageio.v3 as iio

    from anigs.formats.gltf import save_glb
    from tests._scenes import sway_scene

    root, url = site
    g, _ = sway_scene(seed=3, n_dyn=600, grid=40, anisotropic=True)
    save_glb(root / "canonical.glb", g)
    cam = _level_camera()
    centre, target = cam.center, cam.center + cam.R[2]
    opts = {"url": url + "canonical.glb", "width": cam.width, "height": cam.height,
            "fovY": math.degrees(2 * math.atan(cam.height / 2 / cam.K[1, 1])),
            "eye": (Y_UP @ centre).tolist(), "target": (Y_UP @ target).tolist()}
    driver = chrome((1000, 800), webgl=True)
    try:
        driver.set_script_timeout(120)
        driver.get(url + "index.html")
        data = driver.execute_async_script(SCRIPT, opts)
    finally:
        driver.quit()
    assert data.startswith("data:image/png;base64,"), data[:500]
    got = iio.imread(io.BytesIO(base64.b64decode(data.split(",", 1)[1])))[..., :3].astype(np.float64) / 255
    ref = _reference(g, cam)
    iio.imwrite(tmp_path / "playcanvas_sheet.png", (np.concatenate([ref, got], 1) * 255).round().astype(np.uint8))
    diff = float(np.abs(got - ref).mean() * 255)
    print("playcanvas canonical.glb vs anigs, mean abs difference (of 255):", json.dumps(diff), tmp_path)
    assert got.mean() > 0.05 and diff < 10, diff
