"""Viewer benchmark: compact size vs the PLY export, viewer/rasterizer agreement, frame rate.

    python benchmarks/viewer.py --model results/demo/full/round4/model.pt \\
        --canonical results/demo/static/canonical.ply --views results/demo/views/views.json --out /tmp/viewer-bench

1. Sizes: the compact file (``scene.anigs``) vs today's export (T per-frame 3DGS PLYs + the DCT
   PLY ``animated.ply``), both written under ``--out``.
2. Agreement: the viewer's canvas (headless Chromium, WebGL2 on SwiftShader unless a GPU is
   used) vs ``anigs.render`` at the same camera and time, PSNR in dB, for ``--num-views`` queued
   views x ``--times``.
3. Frame rate: ``--frames`` draws at native view resolution and at ``--scales`` multiples, each
   synchronised with a 1-pixel read (render only: the depth sort runs in its worker, its time per
   sort is listed separately).
4. Screenshots of the page (``--out``/shot_*.png).

Writes ``--out``/viewer_bench.json and prints a summary. Needs chromium, chromedriver, selenium.
"""
from __future__ import annotations

import argparse
import base64
import json
import math
import shutil
import time
from pathlib import Path

import numpy as np
import torch

from anigs.stages.export import Outputs as ExportOutputs
from anigs.stages.view import Outputs as ViewOutputs


def _driver(width: int, height: int, gpu: bool):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    flags = ["--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-background-networking",
             "--disable-component-update", "--disable-sync", "--no-first-run", f"--window-size={width},{height}"]
    flags += ["--use-angle=vulkan", "--enable-features=Vulkan", "--ignore-gpu-blocklist"] if gpu else \
        ["--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
    for f in flags:
        opts.add_argument(f)
    drv = webdriver.Chrome(service=Service(shutil.which("chromedriver") or "/usr/bin/chromedriver"), options=opts)
    drv.set_script_timeout(600)
    return drv


def _sizes(out: Path, canonical, deformation) -> dict:
    from anigs.export import save_animated_ply
    from anigs.viewer.compact import save_compact, write_frame_plys

    compact_path, ply_export = ExportOutputs(out).path("compact"), ExportOutputs(out / "ply_export")
    save_compact(compact_path, canonical, deformation)
    frames = write_frame_plys(ply_export.root, canonical, deformation)
    save_animated_ply(ply_export.path("ply"), canonical, deformation)
    frame_bytes = sum((ply_export.root / f).stat().st_size for f in frames)
    dct_ply = ply_export.path("ply").stat().st_size
    compact = compact_path.stat().st_size
    shutil.rmtree(ply_export.root)
    return {"compact_bytes": compact, "frame_plys_bytes": frame_bytes, "num_frame_plys": len(frames),
            "dct_ply_bytes": dct_ply, "today_export_bytes": frame_bytes + dct_ply,
            "ratio_today_over_compact": (frame_bytes + dct_ply) / compact}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", required=True)
    p.add_argument("--canonical", default=None)
    p.add_argument("--views", required=True)
    p.add_argument("--out", default="/tmp/anigs-viewer-bench")
    p.add_argument("--num-views", type=int, default=3)
    p.add_argument("--times", type=float, nargs="+", default=[0.0, 7.5, 24.0])
    p.add_argument("--frames", type=int, default=10)
    p.add_argument("--scales", type=float, nargs="+", default=[1.0, 4.0])
    p.add_argument("--target", default="auto", choices=["auto", "rgba32f", "rgba16f", "rgba8"],
                   help="the viewer's accumulation target (auto: the most precise blendable one)")
    p.add_argument("--gpu", action="store_true", help="hardware WebGL (ANGLE on Vulkan) instead of SwiftShader")
    a = p.parse_args()

    from anigs.render import render_gaussians
    from anigs.viewer.build import build_viewer, load_animated
    from anigs.viewer.serve import start_server
    from anigs.views import cameras_from_views

    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    canonical, deformation, _ = load_animated(a.model, a.canonical)
    result = {"num_gaussians": canonical.num, "num_dynamic": deformation.num_dynamic,
              "num_frames": deformation.num_frames, "num_bases": deformation.num_bases,
              "sh_degree": canonical.sh_degree, "sizes": _sizes(out, canonical, deformation)}
    t0 = time.perf_counter()
    summary = build_viewer(a.model, ViewOutputs(out / "viewer"), a.views, canonical=a.canonical)
    result["build_s"] = time.perf_counter() - t0
    result["viewer_folder_bytes"] = summary["folder_bytes"]
    bg = torch.tensor(json.loads(ViewOutputs(out / "viewer").path("config").read_text().split("=", 1)[1].rstrip().rstrip(";"))
                      ["background"])
    cams = cameras_from_views(json.loads(Path(a.views).read_text()))
    times = [min(max(t, 0.0), deformation.num_frames - 1) for t in a.times]
    server = start_server(ViewOutputs(out / "viewer"))
    drv = _driver(1280, 860, a.gpu)
    try:
        t0 = time.perf_counter()
        drv.get(server.url + f"?scale=1&paused=1&target={a.target}")
        info = drv.execute_async_script("const d = arguments[0]; window.anigsViewer.ready.then("
                                        "v => v.renderExact().then(() => d(v.info())), e => d('ERROR ' + e));")
        if not isinstance(info, dict):
            raise RuntimeError(info)
        result["load_s"] = time.perf_counter() - t0
        result["gl_renderer"] = drv.execute_script(
            "const gl = window.anigsViewer.renderer.gl, e = gl.getExtension('WEBGL_debug_renderer_info');"
            "return e ? gl.getParameter(e.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);")
        agreement = []
        for vi, cam in enumerate(cams[:a.num_views]):
            for t in times:
                b64 = drv.execute_async_script(
                    "const [i, t, d] = arguments, v = window.anigsViewer; v.setView(i); v.setTime(t);"
                    "v.renderExact().then(() => d(v.pixelsBase64()));", vi, t)
                ours = np.frombuffer(base64.b64decode(b64), np.uint8).reshape(cam.height, cam.width, 4)[..., :3] / 255.0
                with torch.no_grad():
                    ref = render_gaussians(deformation(canonical, t), cam, background=bg)[0].clamp(0, 1).numpy()
                mse = float(((ours - ref) ** 2).mean())
                agreement.append({"view": cam.name, "t": t, "psnr_db": 10 * math.log10(1 / max(mse, 1e-12)),
                                  "max_abs": float(np.abs(ours - ref).max())})
                if vi == 0:
                    from PIL import Image

                    Image.fromarray((ours * 255).round().astype(np.uint8)).save(out / f"viewer_v0_t{t:g}.png")
                    Image.fromarray((ref * 255).round().astype(np.uint8)).save(out / f"raster_v0_t{t:g}.png")
        result["agreement"] = agreement
        fps = []
        for s in a.scales:
            drv.get(server.url + f"?scale={s:g}&paused=1&target={a.target}")
            drv.execute_async_script("const d = arguments[0]; window.anigsViewer.ready.then("
                                     "v => v.renderExact().then(() => d(1)));")
            fps.append(drv.execute_script("return window.anigsViewer.benchmark(arguments[0])", a.frames))
        result["frame_rate"] = fps
        drv.get(server.url + f"?paused=1&target={a.target}")  # the page as a user sees it (fit to the window)
        drv.execute_async_script("const d = arguments[0]; window.anigsViewer.ready.then("
                                 "v => { v.setTime(12); return v.renderExact(); }).then(() => d(1));")
        drv.save_screenshot(str(out / "shot_page.png"))
        drv.execute_async_script("const d = arguments[0], v = window.anigsViewer; document.getElementById('moving')"
                                 ".click(); v.renderExact().then(() => d(1));")
        drv.save_screenshot(str(out / "shot_moving.png"))
        from selenium.webdriver.common.action_chains import ActionChains
        from selenium.webdriver.common.by import By

        drv.find_element(By.ID, "moving").click()
        ActionChains(drv).drag_and_drop_by_offset(drv.find_element(By.ID, "canvas"), 250, 40).perform()
        drv.execute_async_script("const d = arguments[0]; window.anigsViewer.renderExact().then(() => d(1));")
        drv.save_screenshot(str(out / "shot_orbit.png"))
    finally:
        drv.quit()
        server.stop()
    (out / "viewer_bench.json").write_text(json.dumps(result, indent=1))
    s = result["sizes"]
    print(f"{result['num_gaussians']} Gaussians, {result['num_dynamic']} dynamic, T={result['num_frames']}, "
          f"K={result['num_bases']}, SH {result['sh_degree']}; renderer: {result['gl_renderer']}")
    print(f"compact {s['compact_bytes'] / 1e6:.2f} MB vs today's export {s['today_export_bytes'] / 1e6:.1f} MB "
          f"({s['num_frame_plys']} frame PLYs {s['frame_plys_bytes'] / 1e6:.1f} MB + DCT PLY "
          f"{s['dct_ply_bytes'] / 1e6:.1f} MB): {s['ratio_today_over_compact']:.1f}x smaller")
    for r in result["agreement"]:
        print(f"  {r['view']:>14s} t={r['t']:<5g} PSNR {r['psnr_db']:.2f} dB  max |diff| {r['max_abs']:.3f}")
    for f in result["frame_rate"]:
        print(f"  {f['width']}x{f['height']}: {f['ms_per_frame']:.1f} ms/frame ({f['fps']:.1f} fps), "
              f"sort {f['sort_ms']:.1f} ms, {f['splats']} splats, target {f['target']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
