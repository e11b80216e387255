"""What every stage downstream of a splat import costs as the splat grows to what GPU trainers make.

    python benchmarks/large_splat.py [--sizes 29908 100000 500000 2000000] [--out /tmp/large_splat]
        [--timeout 2700] [--nice 5] [--table-only] [--profile-failed]

The splats are a stand-in for a GPU trainer's denser splat of the same scene (more and smaller
Gaussians): the demo's fitted splat (``--source``, 29,908 Gaussians at SH 3, in the frame of the
demo's sfm folder) with each Gaussian split into k jittered copies, k = N / 29,908 rounded up, then
trimmed to N (copy-major: every Gaussian keeps k or k - 1 copies). A copy's centre is drawn from the
Gaussian itself (its own rotation and per-axis extent, a standard normal clipped to +-2 sigma, times
sqrt(1 - k^(-2/3))), its scales are shrunk by k^(-1/3) (the k copies fill the original's volume; the
mixture's covariance is the original's), opacity, rotation and SH are copied. A fixed seed makes the
PLY deterministic (``anigs.gaussians.Gaussians.save_ply``). It is not a trained splat: no copy is
placed where the photos need detail the original lacked, so it measures cost, not quality.

For each size the real workflow runs (``snakemake --cores 2``, one benchmark repeat: Snakemake 9 has
no ``--benchmark-repeats`` option and writes one row per job unless a rule says ``repeat()``; its own results
folder, a scene file written here) on the demo's COLMAP project (``--sfm``: its ``images`` and
``sparse``) with ``config/config.yaml`` as it is, scene file ``splat:`` pointing at the PLY in a folder
of its own (no trainer files beside it: the import finds the sfm frame). Per rule it collects wall
seconds, CPU seconds and peak RSS from Snakemake's benchmark TSVs (``anigs.reports.benchmark_tsv``),
the size lines each stage's log prints, the held-out PSNR of the import (``static/metrics.json``), the
files the export and view stages write, and the load average before, during and after the run. A
size already in OUT/results.jsonl is not re-run (``--rerun`` forces it). A failed run (a stage error,
a time-out) is recorded with the failing rule and its log's last lines; ``--profile-failed`` then runs
the failed rule's ``anigs`` command under cProfile and ``/usr/bin/time -v`` (OUT/profile_<N>_<rule>.*).

Prints one markdown table (rows = rules, columns = sizes, cells "wall s / CPU s / peak RSS MiB"), the
log-log growth exponent of CPU s and peak RSS per rule between the two sizes ``--slope`` names (default
0.1 M and 2 M), the output file sizes per size, and the size lines of the logs.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import torch  # noqa: E402

from anigs.gaussians import Gaussians  # noqa: E402
from anigs.geometry.quaternion import quat_to_rotmat  # noqa: E402
from anigs.reports.benchmark_tsv import benchmark_files, rule_breakdown  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
# benchmark file name -> rule (colmap_import writes the sfm rule's files)
RULE_OF_TSV = {"sfm": "colmap_import"}
RULE_ORDER = ["colmap_import", "static", "effects", "views", "masks", "round", "update", "render_clip", "refine",
              "final", "export", "view", "eval_model", "eval"]
SCENE_TEXT = """\
name: {name}
source: colmap
images: {images}
sparse: {sparse}
splat: {splat}
effects: [foliage_sway, leaf_flutter, grass_wave, flower_bob]
prompt: "a garden with trees, bushes, grass and flowers swaying gently in the wind"
background: [0.6, 0.75, 0.9]
static:
  imported:
    background: [0.6, 0.75, 0.9]
"""


# ---- the splats -------------------------------------------------------------------------------

def densify(g: Gaussians, n: int, seed: int = 0) -> Gaussians:
    """``g`` split into ``n`` jittered, shrunk copies (module docstring); ``g`` itself when n <= g.num."""
    if n <= g.num:
        return g.subset(torch.arange(n))
    k = math.ceil(n / g.num)
    gen = torch.Generator().manual_seed(seed)
    src = torch.arange(g.num).repeat(k)[:n]           # copy-major, trimmed: k or k-1 copies each
    src = torch.sort(src, stable=True).values         # a Gaussian's copies side by side
    z = torch.randn(n, 3, generator=gen).clamp_(-2.0, 2.0) * math.sqrt(1.0 - k ** (-2.0 / 3.0))
    R = quat_to_rotmat(g.quats[src])                  # [n,3,3]
    offset = torch.einsum("nij,nj->ni", R, z * g.scales[src])
    return Gaussians(
        means=(g.means[src] + offset).contiguous(),
        quats=g.quats[src].clone(),
        log_scales=(g.log_scales[src] - math.log(k) / 3.0).contiguous(),
        opacity_logits=g.opacity_logits[src].clone(),
        sh=g.sh[src].clone(),
    )


def make_splat(source: Path, n: int, out: Path, seed: int) -> dict:
    """Write the N-Gaussian splat to ``out`` (a folder of its own) unless it is there; its facts."""
    if not out.exists():
        t = time.perf_counter()
        g = densify(Gaussians.load_ply(source), n, seed)
        out.parent.mkdir(parents=True, exist_ok=True)
        g.save_ply(out)
        print(f"wrote {out} ({g.num} Gaussians, SH {g.sh_degree}, {out.stat().st_size / 2**20:.1f} MiB) "
              f"in {time.perf_counter() - t:.1f} s", flush=True)
    return {"path": str(out), "bytes": out.stat().st_size, "k": math.ceil(n / 29908)}


# ---- one workflow run -------------------------------------------------------------------------

def loadavg() -> list[float]:
    return [float(x) for x in Path("/proc/loadavg").read_text().split()[:3]]


def uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def label(n: int) -> str:
    return f"{n / 1e6:g} M" if n >= 100_000 else f"{n / 1e3:.1f} k"


def scene_name(n: int) -> str:
    return f"lsplat_n{n}"


def _snakemake_jobs(text: str) -> tuple[dict[str, str], set[str]]:
    """Jobs Snakemake started (jobid -> rule) and finished, from its output."""
    started: dict[str, str] = {}
    for m in re.finditer(r"^(?:local)?(?:rule|checkpoint) (\w+):\n(?:    .*\n)*?    jobid: (\d+)", text, re.M):
        started[m.group(2)] = m.group(1)
    finished = set(re.findall(r"Finished jobid: (\d+)", text))
    return started, finished


def _failure(text: str, res: Path) -> dict:
    """Which rule failed, its log's last lines and its command, from Snakemake's output."""
    out: dict = {}
    m = re.search(r"Error in rule (\w+):\n((?:    .*\n|        .*\n)*)", text)
    if m:
        out["rule"] = m.group(1)
        block = m.group(2)
        lg = re.search(r"^    log: (\S+)", block, re.M)
        sh = re.search(r"^    shell:\n        (.*)\n", block, re.M)
        if lg:
            out["log"] = lg.group(1)
        if sh:
            out["command"] = sh.group(1).strip()
    else:  # a time-out: the jobs still running
        started, finished = _snakemake_jobs(text)
        running = sorted({r for j, r in started.items() if j not in finished})
        out["running"] = running
        if running:
            out["rule"] = running[0]
    if out.get("log") is None and out.get("rule"):
        logs = sorted(res.rglob(f"logs/**/{out['rule']}*.log")) or sorted(res.rglob(f"logs/{out['rule']}*.log"))
        if out["rule"] == "colmap_import":
            logs = sorted(res.rglob("logs/sfm.log"))
        if logs:
            out["log"] = str(logs[-1])
    if out.get("log") and Path(out["log"]).exists():
        lines = [ln for ln in Path(out["log"]).read_text(errors="replace").splitlines() if "it/s]" not in ln]
        out["log_tail"] = lines[-15:]
    return out


def run_workflow(n: int, splat: Path, args) -> dict:
    name = scene_name(n)
    scenes = args.out / "scenes"
    scenes.mkdir(parents=True, exist_ok=True)
    sfm = Path(args.sfm)
    (scenes / f"{name}.yaml").write_text(SCENE_TEXT.format(
        name=name, images=sfm / "images", sparse=sfm / "sparse", splat=splat))
    results = args.out / f"results_n{n}"
    cmd = ([] if args.nice is None else ["nice", "-n", str(args.nice)]) + [
        str(BIN / "snakemake"), "--cores", str(args.cores),
        "--config", f'scenes=["{name}"]', f"scene_dir={scenes}", f"results={results}"]
    print("$ " + " ".join(shlex.quote(c) for c in cmd), flush=True)
    env = dict(os.environ, PATH=f"{BIN}:{os.environ.get('PATH', '')}")
    log_path = args.out / f"snakemake_n{n}.log"
    rec: dict = {"n": n, "scene": name, "results": str(results), "command": " ".join(shlex.quote(c) for c in cmd),
                 "uptime_before": uptime(), "loadavg_before": loadavg()}
    t0 = time.time()
    samples = []
    with open(log_path, "w") as log:
        p = subprocess.Popen(cmd, cwd=REPO, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        timed_out = False
        while p.poll() is None:
            time.sleep(5)
            if len(samples) == 0 or time.time() - t0 >= 30 * len(samples):
                samples.append(loadavg()[0])
            if time.time() - t0 > args.timeout:
                timed_out = True
                os.killpg(p.pid, signal.SIGTERM)  # the run started here, and its children
                try:
                    p.wait(60)
                except subprocess.TimeoutExpired:
                    os.killpg(p.pid, signal.SIGKILL)
                    p.wait()
    rec.update(rc=p.returncode, timed_out=timed_out, wall_s=round(time.time() - t0, 1),
               uptime_after=uptime(), loadavg_after=loadavg(),
               load1_during={"mean": round(sum(samples) / max(len(samples), 1), 2), "max": max(samples, default=None),
                             "samples": len(samples)},
               snakemake_log=str(log_path))
    text = log_path.read_text(errors="replace")
    rec["ok"] = p.returncode == 0 and not timed_out
    if not rec["ok"]:
        rec["failure"] = _failure(text, results / name)
        rec["failure"]["why"] = f"time-out after {args.timeout} s" if timed_out else f"snakemake exit {p.returncode}"
    rec.update(collect(results / name))
    return rec


# ---- what a run measured ------------------------------------------------------------------------

_SIZE_LINE = re.compile(r"Gaussians|scene_bytes|registered|dynamic\.npy|MB|MiB")


def _size_lines(path: Path, limit: int = 6) -> list[str]:
    lines = [ln for ln in path.read_text(errors="replace").splitlines()
             if _SIZE_LINE.search(ln) and "it/s]" not in ln and "%|" not in ln]
    lines = [re.sub(r"^\d{4}-\d\d-\d\d [\d:,]+ \w+ ", "", ln)[:260] for ln in lines]
    return lines[-limit:]


def _bytes(p: Path) -> int | None:
    if p.is_file():
        return p.stat().st_size
    if p.is_dir():
        return sum(f.stat().st_size for f in p.rglob("*") if f.is_file())
    return None


def collect(scene_dir: Path) -> dict:
    rules = []
    if scene_dir.exists():
        for r in rule_breakdown(benchmark_files(scene_dir)):
            r["rule"] = RULE_OF_TSV.get(r["rule"], r["rule"])
            rules.append(r)
    logs = {}
    for lg in sorted(scene_dir.rglob("logs/**/*.log")) if scene_dir.exists() else []:
        key = str(lg.relative_to(scene_dir))
        if lines := _size_lines(lg):
            logs[key] = lines
    out: dict = {"rules": rules, "log_sizes": logs}
    mj = scene_dir / "static" / "metrics.json"
    if mj.exists():
        m = json.loads(mj.read_text())
        out["static"] = {k: m.get(k) for k in ("test_psnr", "test_ssim", "train_psnr", "num_gaussians", "seconds")}
        out["static"]["frame"] = (m.get("imported") or {}).get("frame")
    ej = scene_dir / "full" / "eval" / "metrics.json"
    if ej.exists():
        e = json.loads(ej.read_text())
        flat = e.get("metrics", e)
        out["eval"] = {k: flat.get(k) for k in ("multiview/psnr_capture", "multiview/psnr_novel") if k in flat}
    files = {}
    exp = scene_dir / "full" / "export"
    for f in sorted(exp.glob("*")) if exp.exists() else []:
        files[f"export/{f.name}"] = _bytes(f)
    for rel in ("full/viewer", "static/canonical.ply"):
        if (b := _bytes(scene_dir / rel)) is not None:
            files[rel.removeprefix("full/")] = b
    if (b := _bytes(scene_dir)) is not None:
        files["results folder"] = b
    out["files"] = files
    return out


def profile_failed(rec: dict, args) -> dict | None:
    """The failed rule's ``anigs`` command again, under cProfile and /usr/bin/time -v."""
    fail = rec.get("failure") or {}
    cmd = fail.get("command")
    if not cmd:
        return None
    cmd = re.sub(r"\s*>\s*\S+\s+2>&1\s*$", "", cmd)
    argv = shlex.split(cmd)
    if not argv or Path(argv[0]).name != "anigs":
        return None
    stem = args.out / f"profile_n{rec['n']}_{fail.get('rule', 'stage')}"
    full = ["/usr/bin/time", "-v", "-o", f"{stem}.time", sys.executable, "-m", "cProfile", "-o", f"{stem}.prof",
            str(BIN / "anigs")] + argv[1:]
    if args.nice is not None:
        full = ["nice", "-n", str(args.nice)] + full
    print("$ " + " ".join(shlex.quote(c) for c in full), flush=True)
    t0 = time.time()
    with open(f"{stem}.log", "w") as log:
        try:
            rc = subprocess.run(full, cwd=REPO, stdout=log, stderr=subprocess.STDOUT, timeout=args.timeout).returncode
        except subprocess.TimeoutExpired:
            rc = "time-out"
    out = {"command": " ".join(shlex.quote(c) for c in full), "rc": rc, "wall_s": round(time.time() - t0, 1)}
    tf = Path(f"{stem}.time")
    if tf.exists():
        t = tf.read_text()
        for key, pat in (("max_rss_kb", r"Maximum resident set size \(kbytes\): (\d+)"),
                         ("user_s", r"User time \(seconds\): ([\d.]+)"), ("sys_s", r"System time \(seconds\): ([\d.]+)")):
            if m := re.search(pat, t):
                out[key] = float(m.group(1))
    pf = Path(f"{stem}.prof")
    if pf.exists():
        import io
        import pstats
        s = io.StringIO()
        pstats.Stats(str(pf), stream=s).sort_stats("cumulative").print_stats(30)
        Path(f"{stem}.txt").write_text(s.getvalue())
        out["top"] = str(Path(f"{stem}.txt"))
    return out


# ---- the tables ---------------------------------------------------------------------------------

def _cell(r: dict | None) -> str:
    if r is None:
        return "-"
    f = lambda x, fmt: "n/a" if x is None else format(x, fmt)  # noqa: E731
    return f"{f(r['seconds'], '.1f')} / {f(r['cpu_seconds'], '.1f')} / {f(r['max_rss_mb'], '.0f')}"


def _slope(a, b, na: int, nb: int):
    if a is None or b is None or a <= 0 or b <= 0:
        return None
    return math.log(b / a) / math.log(nb / na)


def report(recs: list[dict], slope: tuple[int, int]) -> str:
    recs = sorted(recs, key=lambda r: r["n"])
    by_n = {r["n"]: {x["rule"]: x for x in r.get("rules", [])} for r in recs}
    rules = [x for x in RULE_ORDER if any(x in b for b in by_n.values())]
    rules += sorted({x for b in by_n.values() for x in b} - set(rules))
    lo, hi = slope
    have_slope = lo in by_n and hi in by_n
    head = ["rule"] + [f"{label(r['n'])} ({r['n']:,})" + ("" if r["ok"] else " FAILED") for r in recs]
    if have_slope:
        head += [f"CPU exponent {label(lo)}->{label(hi)}", "RSS exponent"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def total(n):
        rs = list(by_n[n].values())
        if not rs:
            return None
        cpu = [x["cpu_seconds"] for x in rs]
        rss = [x["max_rss_mb"] for x in rs if x["max_rss_mb"] is not None]
        return {"seconds": sum(x["seconds"] for x in rs), "cpu_seconds": None if None in cpu else sum(cpu),
                "max_rss_mb": max(rss) if rss else None}

    for name in rules + ["total (sum; RSS: largest)"]:
        cells = []
        for r in recs:
            x = total(r["n"]) if name.startswith("total") else by_n[r["n"]].get(name)
            if x is None and name == "eval" and r["ok"]:
                cells.append("(no benchmark: a run: merge)")
            else:
                cells.append(_cell(x))
        row = [name] + cells
        if have_slope:
            a = total(lo) if name.startswith("total") else by_n[lo].get(name)
            b = total(hi) if name.startswith("total") else by_n[hi].get(name)
            sc = _slope(a and a["cpu_seconds"], b and b["cpu_seconds"], lo, hi)
            sr = _slope(a and a["max_rss_mb"], b and b["max_rss_mb"], lo, hi)
            row += ["-" if sc is None else f"{sc:.2f}", "-" if sr is None else f"{sr:.2f}"]
        lines.append("| " + " | ".join(row) + " |")
    out = ["Cells: wall s / CPU s / peak RSS MiB (Snakemake benchmark TSVs; round: the sum of the 4 round "
           "jobs, RSS the largest)", ""] + lines

    # files
    keys = []
    for r in recs:
        keys += [k for k in r.get("files", {}) if k not in keys]
    out += ["", "| file (MiB) | " + " | ".join(label(r["n"]) for r in recs) + " |", "|" + "---|" * (len(recs) + 1)]
    for k in keys:
        vals = [r.get("files", {}).get(k) for r in recs]
        out.append(f"| {k} | " + " | ".join("-" if v is None else f"{v / 2**20:.1f}" for v in vals) + " |")
    sp = [r.get("splat", {}).get("bytes") for r in recs]
    out.append("| input splat PLY | " + " | ".join("-" if v is None else f"{v / 2**20:.1f}" for v in sp) + " |")

    # import quality, load, failures
    out += ["", "| size | held-out PSNR (dB) | SSIM | train PSNR | frame | snakemake wall s | load before -> during "
            "(mean/max) -> after |", "|---|---|---|---|---|---|---|"]
    for r in recs:
        s = r.get("static") or {}
        ld = r.get("load1_during") or {}
        f = lambda x, fmt=".2f": "-" if x is None else format(x, fmt)  # noqa: E731
        out.append(f"| {label(r['n'])} | {f(s.get('test_psnr'))} | {f(s.get('test_ssim'), '.3f')} | "
                   f"{f(s.get('train_psnr'))} | {s.get('frame', '-')} | {r.get('wall_s')} | "
                   f"{r['loadavg_before'][0]:.2f} -> {f(ld.get('mean'))}/{f(ld.get('max'))} -> {r['loadavg_after'][0]:.2f} |")
    for r in recs:
        if not r["ok"]:
            fl = r.get("failure", {})
            out += ["", f"{label(r['n'])} FAILED in {fl.get('rule')}: {fl.get('why')} (log {fl.get('log')})"]
            out += ["    " + ln for ln in fl.get("log_tail", [])]
            if r.get("profile"):
                out.append(f"    profile: {json.dumps(r['profile'])}")
    return "\n".join(out)


def log_report(recs: list[dict]) -> str:
    out = []
    for r in sorted(recs, key=lambda r: r["n"]):
        out.append(f"\n### {label(r['n'])}: what the stages' logs say about sizes")
        for k, lines in r.get("log_sizes", {}).items():
            out.append(f"{k}:")
            out += [f"    {ln}" for ln in lines]
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[29908, 100_000, 500_000, 2_000_000])
    ap.add_argument("--out", type=Path, default=Path("/tmp/large_splat"))
    ap.add_argument("--source", type=Path, default=Path("results/demo/static/canonical.ply"),
                    help="the fitted splat to split (in the sfm folder's frame)")
    ap.add_argument("--sfm", type=Path, default=Path("results/demo/sfm"),
                    help="a folder with the COLMAP project: images/ and sparse/")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--nice", type=int, default=5, help="niceness of the runs (-1: none)")
    ap.add_argument("--timeout", type=float, default=2700.0, help="seconds per workflow run")
    ap.add_argument("--slope", type=int, nargs=2, default=[100_000, 2_000_000])
    ap.add_argument("--rerun", action="store_true", help="run sizes already in results.jsonl again")
    ap.add_argument("--table-only", action="store_true", help="print the tables of results.jsonl, run nothing")
    ap.add_argument("--profile-failed", action="store_true",
                    help="profile a failed run's failed rule (cProfile + /usr/bin/time -v)")
    args = ap.parse_args(argv)
    args.nice = None if args.nice < 0 else args.nice
    args.out.mkdir(parents=True, exist_ok=True)
    store = args.out / "results.jsonl"
    recs = {}
    if store.exists():
        for ln in store.read_text().splitlines():
            if ln.strip():
                r = json.loads(ln)
                recs[r["n"]] = r  # the last record of a size counts
    if not args.table_only:
        for n in args.sizes:
            if n in recs and not args.rerun:
                print(f"{n}: measured already ({store})", flush=True)
                if args.profile_failed and not recs[n]["ok"] and not recs[n].get("profile"):
                    recs[n]["profile"] = profile_failed(recs[n], args)
                    with open(store, "a") as f:
                        f.write(json.dumps(recs[n]) + "\n")
                continue
            splat = args.out / "splats" / f"n{n}" / "point_cloud.ply"
            facts = make_splat(args.source, n, splat, args.seed)
            rec = run_workflow(n, splat, args)
            rec["splat"] = facts
            print(f"{n}: {'ok' if rec['ok'] else 'FAILED'} in {rec['wall_s']} s", flush=True)
            if not rec["ok"] and args.profile_failed:
                rec["profile"] = profile_failed(rec, args)
            with open(store, "a") as f:
                f.write(json.dumps(rec) + "\n")
            recs[n] = rec
    chosen = [recs[n] for n in sorted(recs)]
    if not chosen:
        print("nothing measured yet")
        return 1
    print(report(chosen, tuple(args.slope)))
    print(log_report(chosen))
    return 0


if __name__ == "__main__":
    sys.exit(main())
