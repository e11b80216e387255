"""The one table of ``benchmarks/gpu_check.sh``: each part's status, time and result, from its work folder.

    python benchmarks/gpu_check_table.py WORK      # WORK/status.tsv, WORK/res/*.json, WORK/demo-results/

Markdown, ready for benchmarks/README.md. A part that failed shows FAILED and the last line of its
log; a skipped part says why.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path


def _load(work: Path, name: str) -> dict:
    p = work / "res" / f"{name}.json"
    try:
        return json.loads(p.read_text())
    except (OSError, ValueError):
        return {}


def _f(x, fmt: str = ".1f", none: str = "?") -> str:
    return none if x is None else format(x, fmt)


def _psnr_at(curve: list[dict], it: int):
    return next((r["test_psnr"] for r in curve if r["iteration"] == it), None)


def _with_cpu(work: Path, name: str, line, cpu_line) -> str:
    """``line(g)`` of part ``name`` and, where its ``name_cpu`` run exists, ``cpu_line(g, c)`` after it."""
    g, c = _load(work, name), _load(work, f"{name}_cpu")
    if not g:
        return ""
    return line(g) + (cpu_line(g, c) if c else "")


def _static(work: Path) -> str:
    def line(g: dict) -> str:
        return (f"{g['device']}/{g['backend']}: {g['iterations']} steps in {_f(g['train_seconds'])} s, step "
                f"{_f(g['step_ms_median'], '.2f')} ms (median), held-out PSNR {_f(g['test_psnr'], '.2f')} dB, "
                f"{g['num_gaussians']} Gaussians")

    def cpu_line(g: dict, c: dict) -> str:
        its = [r["iteration"] for r in c["curve"] if r["iteration"] > 0]
        pairs = ", ".join(f"{i}: {_f(_psnr_at(g['curve'], i), '.2f')} vs {_f(_psnr_at(c['curve'], i), '.2f')}"
                          for i in its)
        ratio = c["step_ms_median"] / g["step_ms_median"] if g.get("step_ms_median") and c.get("step_ms_median") else None
        return (f"; CPU ({c['torch_threads']} threads, {c['iterations']} steps): step {_f(c['step_ms_median'], '.2f')} ms "
                f"({_f(ratio)}x); held-out PSNR at step {pairs} dB")

    return _with_cpu(work, "static", line, cpu_line)


def _static_cpu(work: Path) -> str:
    c = _load(work, "static_cpu")
    return f"see static; {c['iterations']} steps in {_f(c['train_seconds'])} s" if c else ""


def _agree(work: Path) -> str:
    a = _load(work, "agree")
    if not a:
        return ""
    grads = ", ".join(f"{n} {_f(v['min_cos'], '.4f')}/{_f(v['max_rel'], '.3f')}" for n, v in a["worst_grad"].items())
    tol = a["tolerance"]
    from anigs.stages.capture import Outputs as CaptureOutputs  # lazy: the table runs even where torch failed

    model = "the ground truth (the fit failed)" if a.get("model", "").endswith(Path(CaptureOutputs.LAYOUT["gt_gaussians"].name).name) else "the fitted model"
    return (f"{'PASS' if a['pass'] else 'OUTSIDE TOLERANCE'}: {a['backend']} vs CPU kernel on {model}, {a['gaussians']} Gaussians, "
            f"{a['views']} views: image PSNR min {_f(a['min_psnr'], '.1f')} / mean {_f(a['mean_psnr'], '.1f')} dB "
            f"(>= {tol['psnr_db']}); gradient worst cosine/relative L2 error {grads} "
            f"(>= {tol['grad_cos']} / <= {tol['grad_rel']})")


def _ltx(work: Path) -> str:
    r = _load(work, "ltx")
    if not r:
        return ""
    mem = f", peak GPU {_f(r['peak_gpu_mib'], '.0f')} MiB" if r.get("peak_gpu_mib") is not None else ""
    return (f"{r['device']} {r['dtype']}, clip {'x'.join(map(str, r['clip']))} (TxHxW), tiny random weights: "
            f"load {_f(r['load_seconds'], '.2f')} s, refine ({len(r.get('sigmas') or []) - 1} steps) "
            f"{_f(r['refine_seconds'], '.2f')} s, SDS loss+backward {_f(r['sds_seconds'], '.2f')} s, "
            f"finite {r['finite']}{mem}")


def _update(work: Path) -> str:
    def line(g: dict) -> str:
        return (f"{g['device']}/{g['backend']}: {g['steps']} steps in {_f(g['seconds'], '.2f')} s "
                f"({_f(g['steps_per_s'], '.1f')} steps/s), {g['gaussians']} Gaussians ({g['dynamic']} dynamic), "
                f"{g['views']} views {g['size']}x{g['frames']} frames, loss {_f(g['first_loss'], '.4f')} -> "
                f"{_f(g['last_loss'], '.4f')}, finite {g['finite']}")

    return _with_cpu(work, "update", line, lambda g, c: f"; CPU: {_f(c['steps_per_s'], '.2f')} steps/s ({c['steps']} steps)")


def _demo(work: Path) -> str:
    res = work / "demo-results"
    if not res.is_dir():
        return ""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from anigs.reports.benchmark_tsv import benchmark_files, rule_breakdown

    from anigs.stages.final import Outputs as FinalOutputs
    from anigs.stages.static import Outputs as StaticOutputs

    summary = FinalOutputs.LAYOUT["summary"].name
    parts = [f"{len(list(res.glob(f'*/*/final/{summary}')))} {summary}"]
    for m in sorted(res.glob(StaticOutputs.pattern("metrics", StaticOutputs.FOLDER.format(scene="*")))):
        parts.append(f"static held-out PSNR {_f(StaticOutputs(m.parent).json('metrics').get('test_psnr'), '.2f')} dB")
    rows = rule_breakdown(benchmark_files(res))
    if rows:
        parts.append("job seconds by rule: " + ", ".join(f"{r['rule']} {r['seconds']:.1f} ({r['jobs']})" for r in rows[:7]))
    return "; ".join(parts)


def _env(work: Path) -> str:
    e = _load(work, "env")
    if not e:
        return ""
    gpu = f"{e.get('gpu')} (sm {e.get('capability')}, {e.get('gpu_mem_gib')} GiB, CUDA {e.get('torch_cuda')})" \
        if e.get("gpu") else "no GPU"
    pk = ", ".join(f"{k[4:]} {v}" for k, v in e.items() if k.startswith("pkg:") and v)
    return f"{gpu}; {e.get('cpu_count')} CPUs; Python {e.get('python')}, torch {e.get('torch')}; {pk}"


def _gsplat(work: Path) -> str:
    r = _load(work, "gsplat")
    if not r:
        return ""
    how = "loaded an extension built before" if r.get("built_before") else "compiled"
    return f"{how} in {_f(r['seconds'])} s (TORCH_CUDA_ARCH_LIST={r['arch']}, MAX_JOBS={r['max_jobs']})"


SUMMARY = {"env": _env, "gsplat": _gsplat, "static": _static, "static_cpu": _static_cpu, "agree": _agree, "ltx": _ltx,
           "update": _update, "demo": _demo}


def table(work: Path) -> str:
    rows = []
    with open(work / "status.tsv") as fh:
        for line in fh:
            name, status, secs, note = (line.rstrip("\n").split("\t") + ["", "", "", ""])[:4]
            try:
                result = SUMMARY.get(name, lambda w: "")(work)
            except Exception as exc:  # noqa: BLE001 - a malformed result must not hide the others
                result = f"(result unreadable: {exc})"
            text = "; ".join(x for x in (note, result if status in ("OK", "TIMEOUT", "FAILED") else "") if x)
            rows.append(f"| {name} | {status} | {secs} | {text.replace('|', '/')} |")
    return "\n".join(["| part | status | s | result |", "|---|---|---|---|", *rows])


if __name__ == "__main__":
    print(table(Path(sys.argv[1])))
