"""SLURM execution on a real single-node cluster on loopback.

A session fixture starts munged, slurmctld and slurmd with
``workflow/scripts/slurm_cluster.sh`` (installing the Debian packages if missing) and
always stops them by PID at the end. The tests run a workflow through
``snakemake --executor slurm`` with a copy of ``workflow/profiles/slurm`` (memory/threads
clamped to this node, squeue as status command, fast status checks) and check:

* every job went through SLURM: each submission in the Snakemake log has a SLURM job id
  that slurmctld ran to completion, one per non-local job of the DAG; GPU rules asked
  for a GPU (the test cluster declares fake GPUs as GRES);
* the outputs equal a local run of the same config bit for bit;
* fault: a job cancelled with ``scancel`` mid-run is reported as failed, and a rerun
  submits only the jobs still missing (finished outputs are not touched).

Cases: ``tiny`` is the standalone DAG in ``tests/slurm/``; ``workflow`` is the anigs
workflow with its tiny config (``WORKFLOW_TEST_CONFIG``, default ``config/test.yaml``,
override with the environment variable ``ANIGS_SLURM_TEST_CONFIG``).

Run with ``-s`` to see the timing figures (cluster set-up, local vs SLURM, per job).
"""
from __future__ import annotations

import dataclasses
import fnmatch
import hashlib
import os
import re
import shutil
import socket
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "workflow" / "scripts" / "slurm_cluster.sh"
PROFILE = REPO / "workflow" / "profiles" / "slurm" / "config.yaml"
SNAKEMAKE = Path(sys.executable).with_name("snakemake")
TINY = REPO / "tests" / "slurm"
# The anigs workflow's tiny config (the lead adds it); point elsewhere by environment.
WORKFLOW_TEST_CONFIG = Path(os.environ.get("ANIGS_SLURM_TEST_CONFIG", REPO / "config" / "test.yaml"))

RUN_TIMEOUT_S = 240  # one snakemake invocation (killed with `timeout -k`)
CLUSTER_TIMEOUT_S = 420  # cluster start, including apt-get when the packages are missing
NODE_MEM_MB = 1000  # per-job memory cap on the test node (the profile asks for 16-32 GB)

pytestmark = pytest.mark.slow


@dataclasses.dataclass(frozen=True)
class Case:
    name: str
    snakefile: Path
    configfile: Path | None
    results: str  # folder (relative to the work dir) whose files must match bit for bit
    ignore: tuple[str, ...]  # glob patterns (relative to `results`) left out of the comparison
    cancel_rule: str  # the fault test cancels a running job of this rule
    cancel_wildcards: str | None = None  # ... whose wildcard string (comment suffix) is this
    cancel_when_log: tuple[str, str] | None = None  # ... once this file contains this text
    fault_config: tuple[str, ...] = ()  # --config entries for the run that gets cancelled
    rerun_config: tuple[str, ...] = ()  # --config entries for the rerun
    timeout_s: int = RUN_TIMEOUT_S  # limit of one snakemake invocation
    local_rules: tuple[str, ...] = ("all",)  # `localrules:` of the workflow (not submitted)
    sibling_finishes: bool = False  # another job of cancel_rule finishes in the cancelled run
    config: tuple[str, ...] = ()  # --config entries of every run of the case (local ones included)


CASES = [
    Case(
        name="tiny",
        snakefile=TINY / "Snakefile",
        configfile=None,
        results="results",
        ignore=("logs/*",),
        cancel_rule="refine",
        cancel_wildcards="1",
        cancel_when_log=("results/logs/refine_1.log", "sleeping"),
        fault_config=("slow_view=1", "slow_seconds=120"),
        rerun_config=("slow_view=1", "slow_seconds=0"),
        sibling_finishes=True,
    ),
    Case(
        name="workflow",
        snakefile=REPO / "Snakefile",
        configfile=WORKFLOW_TEST_CONFIG,
        results="results",
        # JSON reports record wall-clock seconds; every data artifact (images, clips, PLYs,
        # models, masks, videos) must match bit for bit
        ignore=("*.log", "*/logs/*", "logs/*", "benchmarks/*", "*/benchmarks/*", "*.json"),
        cancel_rule="refine",
        timeout_s=600,
        # the local reference and the dry runs split rounds into per-view jobs like the cluster
        # (round_jobs: auto would give one job per round locally; the files are the same)
        config=("round_jobs=view",),
        # eval joins the two halves of the metrics (a JSON merge) inside Snakemake
        local_rules=("all", "eval"),
    ),
]


# --------------------------------------------------------------------------- helpers


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _tail(text: str, n: int = 60) -> str:
    return "\n".join(text.splitlines()[-n:])


@dataclasses.dataclass
class Cluster:
    state: Path
    env: dict[str, str]  # for clients: SLURM_CONF, the venv first on PATH
    script_env: dict[str, str]  # for slurm_cluster.sh: ports of this cluster
    setup_s: float

    @property
    def ctld_log(self) -> Path:
        return self.state / "log" / "slurmctld.log"

    def cmd(self, *args: str, timeout: float = 20) -> str:
        out = subprocess.run(
            ["timeout", "-k", "2", str(timeout), *args],
            env=self.env, capture_output=True, text=True, check=False,
        )
        if out.returncode != 0:
            raise RuntimeError(f"{' '.join(args)} failed ({out.returncode}): {out.stderr}")
        return out.stdout

    def jobs(self) -> dict[str, dict[str, str]]:
        """All jobs slurmctld still knows (MinJobAge=600 keeps finished ones): id -> fields."""
        out = self.cmd("squeue", "--states=all", "--noheader", "--format=%i|%j|%T|%k")
        jobs = {}
        for line in out.splitlines():
            jid, name, state, comment = (line.split("|") + ["", "", "", ""])[:4]
            jobs[jid.strip()] = {"name": name, "state": state.strip(), "comment": comment.strip()}
        return jobs

    def job_field(self, jid: str, key: str) -> str:
        out = self.cmd("scontrol", "show", "job", jid)
        m = re.search(rf"\b{key}=(\S*)", out)
        return m.group(1) if m else ""


def _script(action: str, state: Path, env: dict[str, str], timeout: float) -> subprocess.CompletedProcess:
    return subprocess.run(
        ["timeout", "-k", "10", str(timeout), "bash", str(SCRIPT), action, str(state)],
        env=env, capture_output=True, text=True, check=False,
    )


@pytest.fixture(scope="session")
def slurm_cluster(tmp_path_factory) -> Cluster:
    import importlib.util

    assert importlib.util.find_spec("snakemake_executor_plugin_slurm") is not None, (
        "snakemake-executor-plugin-slurm is not installed: pip install -e '.[slurm]'")
    have = all(shutil.which(b) for b in ("munged", "slurmctld", "slurmd", "sbatch", "squeue"))
    if not have and (os.geteuid() != 0 or shutil.which("apt-get") is None):
        pytest.skip("SLURM/munge Debian packages are not installed and cannot be installed here "
                    "(needs root and apt-get): apt-get install slurmctld slurmd slurm-client munge")
    if os.geteuid() != 0:
        pytest.skip("the loopback SLURM cluster needs root (slurmd starts jobs as their users)")
    state = tmp_path_factory.mktemp("slurm-cluster")
    env = dict(os.environ)
    env.update(ANIGS_SLURM_CTLD_PORT=str(_free_port()), ANIGS_SLURMD_PORT=str(_free_port()),
               ANIGS_SLURM_KEEP_LOGS="1")
    t0 = time.monotonic()
    try:
        started = _script("start", state, env, CLUSTER_TIMEOUT_S)
        setup_s = time.monotonic() - t0
        if started.returncode == 3:
            pytest.skip(f"cannot set up SLURM here: {started.stderr.strip()[-500:]}")
        assert started.returncode == 0, f"cluster start failed:\n{started.stderr[-4000:]}"
        pids = {p.name: int(p.read_text()) for p in (state / "pids").iterdir()}
        assert set(pids) == {"munged", "slurmctld", "slurmd"}, pids
        client_env = dict(os.environ)
        client_env["SLURM_CONF"] = str(state / "slurm.conf")
        client_env["PATH"] = f"{SNAKEMAKE.parent}{os.pathsep}{client_env.get('PATH', '')}"
        print(f"\n[slurm] cluster set-up: {setup_s:.2f} s (pids {pids})")
        yield Cluster(state=state, env=client_env, script_env=env, setup_s=setup_s)
    finally:
        pids = {}
        if (state / "pids").is_dir():
            pids = {p.name: int(p.read_text()) for p in (state / "pids").iterdir() if p.read_text().strip()}
        stopped = _script("stop", state, env, 120)
        still = [f"{n}={p}" for n, p in pids.items() if _alive(p)]
        assert stopped.returncode == 0 and not still, (
            f"cluster stop failed (rc {stopped.returncode}, alive: {still}):\n{stopped.stderr[-2000:]}")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    # a zombie is as good as gone
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ")[1][0] != "Z"
    except (OSError, IndexError):
        return False


def _test_profile(dest: Path) -> Path:
    """The project's SLURM profile, with test-only settings: memory and threads clamped to
    the test node, squeue as status command (no slurmdbd), fast first status check."""
    prof = yaml.safe_load(PROFILE.read_text())
    prof["default-resources"]["mem_mb"] = min(int(prof["default-resources"]["mem_mb"]), NODE_MEM_MB)
    for res in prof.get("set-resources", {}).values():
        if "mem_mb" in res:
            res["mem_mb"] = min(int(res["mem_mb"]), NODE_MEM_MB)
    ncpu = os.cpu_count() or 1
    prof["set-threads"] = {r: min(int(t), ncpu) for r, t in prof.get("set-threads", {}).items()}
    prof.update({
        "slurm-status-command": "squeue",
        "slurm-init-seconds-before-status-checks": 1,
        "slurm-no-account": True,
        "latency-wait": 5,
        "jobs": 8,
    })
    dest.mkdir(parents=True, exist_ok=True)
    (dest / "config.yaml").write_text(yaml.safe_dump(prof, sort_keys=False))
    return dest


@pytest.fixture(scope="session")
def test_profile(tmp_path_factory) -> Path:
    return _test_profile(tmp_path_factory.mktemp("profile"))


def _require(case: Case) -> None:
    if case.configfile is not None and not case.configfile.is_file():
        pytest.skip(f"{case.configfile} does not exist yet: the workflow's tiny config is added "
                    "with the workflow (set ANIGS_SLURM_TEST_CONFIG to use another file)")


def _snakemake(case: Case, workdir: Path, env: dict[str, str], *args: str,
               config: tuple[str, ...] = (), timeout: float | None = None):
    """Run snakemake in `workdir`; returns (returncode, combined output, seconds)."""
    cmd = ["timeout", "-k", "10", str(timeout or case.timeout_s), str(SNAKEMAKE),
           "--snakefile", str(case.snakefile)]
    if case.configfile is not None:
        cmd += ["--configfile", str(case.configfile)]
    if case.config or config:
        cmd += ["--config", *case.config, *config]
    cmd += ["--nocolor", *args]
    workdir.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    out = subprocess.run(cmd, cwd=workdir, env=env, capture_output=True, text=True, check=False)
    return out.returncode, out.stdout + out.stderr, time.monotonic() - t0


def _planned_jobs(case, workdir, env, config=()) -> Counter:
    """Jobs per rule that a run would execute, from the dry run's job blocks, without the
    case's local rules (they run on the submitting host by design)."""
    rc, log, _ = _snakemake(case, workdir, env, "--dry-run", "--cores", "1", config=config, timeout=120)
    assert rc == 0, _tail(log)
    return _job_rules(case, log)


def _job_rules(case: Case, log: str) -> Counter:
    """Jobs per rule in a run's or dry run's log (checkpoints included), without the case's local rules."""
    found = re.findall(r"^(?:local)?(?:rule|checkpoint) (\w+):$", log, flags=re.M)
    return Counter(r for r in found if r not in case.local_rules)


def _check_local_jobs(case: Case, log: str) -> None:
    """Only the rules the case declares local ran outside SLURM."""
    local = set(re.findall(r"^localrule (\w+):$", log, flags=re.M))
    assert local <= set(case.local_rules), f"jobs ran locally, not through SLURM: {local - set(case.local_rules)}"


SUBMIT_RE = re.compile(r"Job (\d+) has been submitted with SLURM jobid (\d+)")


def _submitted(log: str) -> list[str]:
    return [m.group(2) for m in SUBMIT_RE.finditer(log)]


def _rule_of(comment: str) -> str:
    m = re.match(r"rule_(.+?)(?:_wildcards_.*)?$", comment)
    return m.group(1) if m else comment


def _digests(root: Path, ignore: tuple[str, ...]) -> dict[str, str]:
    out = {}
    for p in sorted(root.rglob("*")):
        rel = p.relative_to(root).as_posix()
        if p.is_file() and not any(fnmatch.fnmatch(rel, pat) for pat in ignore):
            out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


_LOCAL: dict[str, tuple[dict[str, str], float, int]] = {}
_LOCAL_JOBS: dict[str, Counter] = {}


def _local_reference(case: Case, root: Path) -> tuple[dict[str, str], float, int]:
    """Digests of a local run of the case (once per session), its time and job count (its jobs per
    rule in ``_LOCAL_JOBS``)."""
    if case.name not in _LOCAL:
        env = dict(os.environ)
        env["PATH"] = f"{SNAKEMAKE.parent}{os.pathsep}{env.get('PATH', '')}"
        workdir = root / f"local-{case.name}"
        rc, log, secs = _snakemake(case, workdir, env, "--cores", "2")
        assert rc == 0, f"local run failed:\n{_tail(log)}"
        njobs = len(re.findall(r"^(?:local)?(?:rule|checkpoint) \w+:", log, flags=re.M))
        _LOCAL_JOBS[case.name] = _job_rules(case, log)
        digests = _digests(workdir / case.results, case.ignore)
        assert digests, f"local run wrote nothing under {workdir / case.results}"
        _LOCAL[case.name] = (digests, secs, njobs)
    return _LOCAL[case.name]


def _procs_in(workdir: Path) -> list[str]:
    """Live processes whose working directory is `workdir` (pid: command line)."""
    found = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            if Path(os.readlink(proc / "cwd")) == workdir:
                stat = (proc / "stat").read_text()
                if stat.rsplit(") ", 1)[1][0] != "Z":
                    cmdline = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
                    found.append(f"{proc.name}: {cmdline[:120]}")
        except (OSError, IndexError):
            continue
    return found


def _ctld_times(cluster: Cluster, jid: str) -> tuple[float, float] | None:
    """Submit and completion time (epoch seconds) of a job from slurmctld's log."""
    text = cluster.ctld_log.read_text(errors="replace")
    stamp = r"\[(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d+)\]"
    sub = re.search(stamp + rf" _slurm_rpc_submit_batch_job: JobId={jid} ", text)
    end = re.search(stamp + rf" _job_complete: JobId={jid} done", text)
    if not (sub and end):
        return None
    from datetime import datetime
    f = "%Y-%m-%dT%H:%M:%S.%f"
    return datetime.strptime(sub.group(1), f).timestamp(), datetime.strptime(end.group(1), f).timestamp()


# --------------------------------------------------------------------------- tests


def test_cluster_script_is_idempotent(slurm_cluster):
    """`start` on a running cluster leaves it alone; `status` sees it; the node offers the
    fake GPUs the profile's GPU rules need."""
    pids = {p.name: p.read_text() for p in (slurm_cluster.state / "pids").iterdir()}
    again = _script("start", slurm_cluster.state, slurm_cluster.script_env, 60)
    assert again.returncode == 0 and "already running" in again.stderr, again.stderr
    assert {p.name: p.read_text() for p in (slurm_cluster.state / "pids").iterdir()} == pids
    assert _script("status", slurm_cluster.state, slurm_cluster.script_env, 60).returncode == 0
    node = slurm_cluster.cmd("sinfo", "--noheader", "--Node", "--format=%T|%G").strip()
    assert node.startswith(("idle", "mix", "alloc")) and "gpu:2" in node, node


def _start(case, cluster, tmp_path_factory, prefix: str):
    """(reference digests, local seconds, local jobs, a fresh work folder, the cluster's jobs so far)
    for a SLURM run of ``case`` (skips when the case cannot run here)."""
    _require(case)
    ref, local_s, local_jobs = _local_reference(case, tmp_path_factory.getbasetemp())
    return ref, local_s, local_jobs, tmp_path_factory.mktemp(f"{prefix}-{case.name}"), set(cluster.jobs())


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_every_job_runs_through_slurm_and_matches_local(case, slurm_cluster, test_profile, tmp_path_factory):
    cluster = slurm_cluster
    ref, local_s, local_jobs, workdir, before = _start(case, cluster, tmp_path_factory, "slurm")
    # the jobs the local run ran (a dry run cannot see past the effects checkpoint on a fresh run)
    planned = _LOCAL_JOBS[case.name]
    assert sum(planned.values()) > 0
    rc, log, slurm_s = _snakemake(case, workdir, cluster.env, "--profile", str(test_profile))
    assert rc == 0, f"SLURM run failed (rc {rc}):\n{_tail(log, 120)}"

    # Every non-local job of the DAG was submitted once and slurmctld completed it.
    _check_local_jobs(case, log)
    ids = _submitted(log)
    assert len(ids) == len(set(ids)) == sum(planned.values()), (ids, planned)
    jobs = cluster.jobs()
    assert set(jobs) - before == set(ids), "jobs in slurmctld differ from the submissions in the log"
    assert all(jobs[j]["state"] == "COMPLETED" for j in ids), {j: jobs[j]["state"] for j in ids}
    assert Counter(_rule_of(jobs[j]["comment"]) for j in ids) == planned
    ctld = cluster.ctld_log.read_text(errors="replace")
    for j in ids:
        assert re.search(rf"_job_complete: JobId={j} WEXITSTATUS 0", ctld), f"job {j} not in slurmctld.log"
    # The profile's GPU rules asked SLURM for a GPU (fake GRES on the test node).
    gpu_rules = {r for r, res in yaml.safe_load(PROFILE.read_text())["set-resources"].items() if res.get("gpu")}
    for j in ids:
        if _rule_of(jobs[j]["comment"]) in gpu_rules:
            assert "gpu" in cluster.job_field(j, "TresPerJob"), f"job {j} ({jobs[j]['comment']}) got no GPU"

    # Outputs equal the local run bit for bit.
    got = _digests(workdir / case.results, case.ignore)
    assert got == ref

    spans = [t[1] - t[0] for t in (_ctld_times(cluster, j) for j in ids) if t]
    print(f"\n[slurm:{case.name}] {len(ids)} jobs; end-to-end local {local_s:.1f} s ({local_jobs} jobs incl. "
          f"local rules), through SLURM {slurm_s:.1f} s; overhead per job (e2e difference / jobs) "
          f"{(slurm_s - local_s) / len(ids):.1f} s; submit->complete per job in slurmctld: mean "
          f"{sum(spans) / max(len(spans), 1):.1f} s, min {min(spans, default=0):.1f} s, "
          f"max {max(spans, default=0):.1f} s; cluster set-up {cluster.setup_s:.2f} s")


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_cancelled_job_fails_and_rerun_resumes(case, slurm_cluster, test_profile, tmp_path_factory):
    cluster = slurm_cluster
    ref, _, _, workdir, before = _start(case, cluster, tmp_path_factory, "fault")

    cmd = ["timeout", "-k", "10", str(case.timeout_s), str(SNAKEMAKE), "--snakefile", str(case.snakefile),
           "--nocolor", "--profile", str(test_profile)]
    if case.configfile is not None:
        cmd += ["--configfile", str(case.configfile)]
    if case.config or case.fault_config:
        cmd += ["--config", *case.config, *case.fault_config]
    logf = workdir / "run1.log"
    with open(logf, "w") as fh:
        proc = subprocess.Popen(cmd, cwd=workdir, env=cluster.env, stdout=fh, stderr=subprocess.STDOUT)
    victim = None
    try:
        # Find a RUNNING job of the rule to cancel (bounded wait), then cancel it.
        deadline = time.monotonic() + case.timeout_s - 30
        while victim is None and time.monotonic() < deadline and proc.poll() is None:
            for jid, job in cluster.jobs().items():
                if jid in before or job["state"] != "RUNNING":
                    continue
                if _rule_of(job["comment"]) != case.cancel_rule:
                    continue
                if case.cancel_wildcards and not job["comment"].endswith("_wildcards_" + case.cancel_wildcards):
                    continue
                if case.cancel_when_log:
                    f = workdir / case.cancel_when_log[0]
                    if not (f.is_file() and case.cancel_when_log[1] in f.read_text(errors="replace")):
                        continue
                victim = jid
                break
            else:
                time.sleep(0.2)
        assert victim is not None, f"no running {case.cancel_rule} job to cancel:\n{_tail(logf.read_text())}"
        cluster.cmd("scancel", victim)
        rc = proc.wait(timeout=case.timeout_s + 20)
    finally:
        if proc.poll() is None:  # SIGTERM reaches snakemake through `timeout`; it cancels its jobs
            proc.terminate()
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=30)
    log1 = logf.read_text(errors="replace")

    # The cancelled job is reported as failed, and the run fails.
    assert rc != 0, f"run with a cancelled job succeeded:\n{_tail(log1)}"
    assert cluster.jobs()[victim]["state"] == "CANCELLED"
    assert re.search(rf"SLURM-job '{victim}' failed, SLURM status is: 'CANCELLED'", log1), _tail(log1, 120)
    victim_comment = cluster.jobs()[victim]["comment"]
    # SLURM really killed the job's processes: once Snakemake has exited, nothing runs in
    # the work dir any more (bounded wait: KillWait=2 s on the test cluster).
    deadline = time.monotonic() + 20
    while _procs_in(workdir) and time.monotonic() < deadline:
        time.sleep(0.5)
    assert not _procs_in(workdir), f"processes of the cancelled job survive: {_procs_in(workdir)}"
    ids1 = _submitted(log1)
    jobs = cluster.jobs()
    done1 = {jobs[j]["comment"] for j in ids1 if jobs[j]["state"] == "COMPLETED"}
    assert done1, "no job finished before the cancelled one: nothing to check the rerun against"
    _check_local_jobs(case, log1)
    if case.sibling_finishes:  # keep-going (profile): the other jobs of the round completed
        assert any(_rule_of(c) == case.cancel_rule for c in done1), done1
    files1 = {p: p.stat().st_mtime_ns for p in (workdir / case.results).rglob("*")
              if p.is_file() and not any(fnmatch.fnmatch(p.relative_to(workdir / case.results).as_posix(), pat)
                                         for pat in case.ignore)}

    # The rerun submits exactly what is missing: the cancelled job and what depends on it.
    planned = _planned_jobs(case, workdir, cluster.env, config=case.rerun_config)
    rc2, log2, _ = _snakemake(case, workdir, cluster.env, "--profile", str(test_profile),
                              config=case.rerun_config)
    assert rc2 == 0, f"rerun failed:\n{_tail(log2, 120)}"
    _check_local_jobs(case, log2)
    jobs = cluster.jobs()
    ids2 = _submitted(log2)
    comments2 = [jobs[j]["comment"] for j in ids2]
    assert all(jobs[j]["state"] == "COMPLETED" for j in ids2)
    assert Counter(_rule_of(c) for c in comments2) == planned
    assert victim_comment in comments2
    assert not done1 & set(comments2), f"rerun redid finished jobs: {done1 & set(comments2)}"
    for p, mtime in files1.items():
        assert p.stat().st_mtime_ns == mtime, f"rerun rewrote {p}"

    assert _digests(workdir / case.results, case.ignore) == ref
    print(f"\n[slurm:{case.name}] cancelled job {victim} ({victim_comment}); run 1 finished {len(done1)} jobs, "
          f"rerun submitted {len(ids2)}: {sorted(comments2)}")
