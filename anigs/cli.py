"""``anigs`` command line: one subcommand per workflow stage.

Each stage's command is its module ``anigs/stages/<name>.py``, run by :mod:`anigs.stages.command`
(by default its flags are its ``Inputs``' fields plus ``--params``, its ``Config``). The command table
derives from the stage registry :data:`anigs.stages.STAGES`. Stage parameters come as the config
section in JSON (``--params '{...}'`` or ``--params @file.json``) so Snakemake can pass
its ``params:`` verbatim; paths are explicit options.

Commands chain with ``--then``: ``anigs --threads 2 round ... --then update ...`` runs them one
after another in one process (the global options apply to each; the first that fails stops the
chain and gives its exit status). The workflow runs a round's render, refine and model update so
(``round_jobs: round``): one Python and torch start-up per round instead of two.
"""
from __future__ import annotations

import argparse
import importlib
import logging
import sys

from anigs.stages.command import parse_params, stage_arguments, stage_main  # noqa: F401 (parse_params: benchmarks')

# tools that are not pipeline stages: command -> (module, one-line help)
TOOLS: dict[str, tuple[str, str]] = {
    "build-kernel": ("anigs.build_kernel", "compile the CPU rasterizer kernel ahead of time"),
    "study": ("anigs.stages.study", "2AFC user study (paper Table 4): build the page, serve it, tally the answers"),
}


def commands() -> dict[str, tuple[str, str]]:
    """Every ``anigs`` command -> (module, help): the stages of :data:`anigs.stages.STAGES`, then the tools."""
    from anigs.stages import STAGES

    return {**{s.name: (s.module, s.help) for s in STAGES if s.command}, **TOOLS}


THEN = "--then"


def _split_chain(argv: list[str]) -> list[list[str]]:
    """``[global options] CMD ARGS --then CMD ARGS ...`` -> one argv per command, each with the global options."""
    parts: list[list[str]] = [[]]
    for a in argv:
        if a == THEN:
            parts.append([])
        else:
            parts[-1].append(a)
    if len(parts) == 1:
        return parts
    table = commands()
    first = parts[0]
    cmd_at = next((i for i, a in enumerate(first) if a in table), None)
    if cmd_at is None or any(not p or p[0] not in table for p in parts[1:]):
        raise SystemExit(f"anigs: {THEN} must separate commands (anigs [options] CMD ARGS {THEN} CMD ARGS ...)")
    glob = first[:cmd_at]
    return [first] + [glob + p for p in parts[1:]]


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    chain = _split_chain(argv)
    if len(chain) > 1:
        import time

        for k, part in enumerate(chain):
            t0 = time.perf_counter()
            rc = _main(part)
            logging.getLogger("anigs").info("chain: command %d of %d (%s) took %.2f s, exit %d", k + 1, len(chain),
                                            next(a for a in part if a in commands()), time.perf_counter() - t0, rc)
            if rc:
                return rc
        logging.getLogger("anigs").info("chain: %d commands, process CPU %.2f s", len(chain), time.process_time())
        return 0
    return _main(argv)


def _main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="anigs", description=__doc__.splitlines()[0])
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    parser.add_argument("--threads", type=int, default=None,
                        help="CPU threads for torch and the rasterizer (Snakemake passes {threads})")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    modules = {}
    table = commands()
    from anigs.stages import RENAMED

    old = next((a for a in argv if a in RENAMED and a not in table), None)
    if old is not None and not any(a in table for a in argv):
        parser.error(f"command {old!r} is now called {RENAMED[old]!r}")
    wanted = next((a for a in argv if a in table), None)
    for name, (mod, help_) in table.items():
        p = sub.add_parser(name, help=help_)
        if name == wanted:  # import lazily: only the chosen stage's dependencies load
            try:
                modules[name] = importlib.import_module(mod)
            except ModuleNotFoundError as exc:
                if exc.name == mod:
                    parser.error(f"stage {name!r} is not implemented in this version of anigs")
                raise
            stage_arguments(modules[name], name, p)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    if args.command is None:
        parser.print_help()
        return 2
    if args.threads:
        import torch

        torch.set_num_threads(max(1, args.threads))
    try:
        return int(stage_main(modules[args.command], args) or 0)
    except (ValueError, FileNotFoundError, RuntimeError, KeyError) as exc:
        logging.getLogger("anigs").error("%s: %s", type(exc).__name__, exc)
        if args.verbose:
            raise
        return 1


if __name__ == "__main__":
    sys.exit(main())
