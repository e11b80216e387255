"""``anigs build-kernel``: compile the CPU rasterizer now (the set-up script calls this)."""
from __future__ import annotations

import argparse


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quiet", action="store_true")


def main(args: argparse.Namespace) -> int:
    from anigs.render import _build

    path = _build.build(verbose=not args.quiet)
    _build.load()
    if not args.quiet:
        print(f"cpu rasterizer ready: {path}")
    return 0
