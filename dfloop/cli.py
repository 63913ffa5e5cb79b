"""Command-line entry point.

``dfloop run models/<scene>.toml [--out DIR]`` runs a loop study: it predicts the limit cycles, verifies them by
closed-loop simulation if the scene asks for it, draws the plots it names and writes a markdown report.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dfloop", description="Describing-function limit-cycle studies.")
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command")
    run = sub.add_parser("run", help="run one or more scene files (models/*.toml)")
    run.add_argument("scenes", nargs="+", type=Path, help="scene files")
    run.add_argument("--out", type=Path, default=Path("out"), help="output directory (default: out/)")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if args.version:
        from . import __version__

        print(f"dfloop {__version__}")
        return 0
    if args.command != "run":
        parser.print_help()
        return 2
    from .scene import load_scene, run_scene

    for path in args.scenes:
        try:
            scene = load_scene(path)
        except ValueError as err:
            print(f"dfloop: {err}", file=sys.stderr)
            return 1
        run_scene(scene, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
