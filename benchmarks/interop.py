"""Read a run's static exports back with third-party readers and print how far they are from
``static/canonical.ply``.

    python benchmarks/interop.py RESULTS/SCENE/VARIANT

``export/canonical.spz`` through splat-transform (to PLY) and gsply; ``export/canonical.glb``
through pygltflib (positions, and the rest of the attributes) and Khronos's glTF validator
(``.node/``, ``envs/npm.sh``). Prints the largest position error of each reader and the SPZ
position step (1/4096).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
NODE = ROOT / ".node"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("variant", type=Path)
    a = ap.parse_args()

    import gsply
    import pygltflib

    from anigs.gaussians import load_ply

    ply = load_ply(a.variant.parent / "static" / "canonical.ply")
    means = ply.means.double().numpy()
    spz, glb = a.variant / "export" / "canonical.spz", a.variant / "export" / "canonical.glb"
    out = {"gaussians": ply.num, "sh_degree": ply.sh_degree, "spz_bytes": spz.stat().st_size,
           "glb_bytes": glb.stat().st_size, "ply_bytes": (a.variant.parent / "static" / "canonical.ply").stat().st_size,
           "spz_position_step": 1 / 4096}
    with tempfile.TemporaryDirectory() as tmp:
        back = Path(tmp) / "back.ply"
        cli = NODE / "node_modules" / "@playcanvas" / "splat-transform" / "bin" / "cli.mjs"
        subprocess.run(["node", str(cli), "-q", "-w", str(spz), str(back)], check=True)
        st = load_ply(back)
        out["spz_splat_transform_max_position_error"] = float(np.abs(st.means.double().numpy() - means).max())
        out["spz_splat_transform_max_log_scale_error"] = float((st.log_scales - ply.log_scales).abs().max())
    gs = gsply.read_spz(spz)
    out["spz_gsply_max_position_error"] = float(np.abs(np.asarray(gs.means, np.float64) - means).max())
    gl = pygltflib.GLTF2().load(str(glb))
    prim = gl.meshes[0].primitives[0]
    acc = gl.accessors[prim.attributes.POSITION]
    view = gl.bufferViews[acc.bufferView]
    pos = np.frombuffer(gl.binary_blob(), np.float32, acc.count * 3, view.byteOffset).reshape(-1, 3)
    out["glb_pygltflib_max_position_error"] = float(np.abs(pos - means).max())
    out["glb_node_rotation_xyzw"] = gl.nodes[0].rotation
    js = ("import { validateBytes } from 'gltf-validator'; import { readFileSync } from 'fs';"
          "const r = await validateBytes(new Uint8Array(readFileSync(process.argv[1])), {maxIssues: 1000});"
          "console.log(JSON.stringify(r.issues));")
    res = subprocess.run(["node", "--input-type=module", "-e", js, str(glb.resolve())], cwd=NODE, check=True,
                         capture_output=True, text=True)
    issues = json.loads(res.stdout)
    codes: dict[str, int] = {}
    for m in issues["messages"]:
        codes[m["code"]] = codes.get(m["code"], 0) + 1
    out["gltf_validator"] = {"errors": issues["numErrors"], "warnings": issues["numWarnings"], "codes": codes}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
