"""Command-line entry point: ``dfloop run|list|scene-keys|cache``.

``dfloop run <scene> [<scene> ...] [--out DIR] [--quiet]`` runs loop studies: each scene is a TOML file or the
name of a shipped scene (``dfloop list``). Every scene is checked before any runs; a bad one is reported (file,
key, closest valid name) and the others still run; the exit code is 1 if any failed. Progress is shown for the
long stages (a bar on a terminal, plain lines in logs); ``--quiet`` turns it and the stage lines off.

This module imports nothing heavy at import time, so ``dfloop --help`` answers at once.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="dfloop", description="Describing-function limit-cycle studies.")
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command")
    run = sub.add_parser("run", help="run scenes: TOML files or names of shipped scenes (see `dfloop list`)")
    run.add_argument("scenes", nargs="+", help="scene files or shipped scene names")
    run.add_argument("--out", type=Path, default=Path("out"), help="output directory (default: out/)")
    run.add_argument("--quiet", action="store_true", help="no progress and no stage lines (errors only)")
    sub.add_parser("list", help="list the shipped scenes with their titles")
    sub.add_parser("scene-keys", help="print every section and key a scene accepts (docs/scenes.md)")
    cache = sub.add_parser("cache", help="the table cache: `info` (files and size per code version) or `clear`")
    cache.add_argument("action", choices=("info", "clear"))
    cache.add_argument("--stale", action="store_true", help="clear only files of other code versions")
    return parser


def _run(args: argparse.Namespace) -> int:
    from .scene import load_scene, run_scene

    scenes, failed = [], []
    for name in args.scenes:  # check every scene first: a typo in the last one should not wait for the others
        try:
            scenes.append(load_scene(name, progress=not args.quiet))
        except ValueError as err:
            print(f"dfloop: {err}", file=sys.stderr)
            failed.append(name)
    for scene in scenes:
        try:
            run_scene(scene, args.out, log=(lambda message: None) if args.quiet else print,
                      progress=not args.quiet)
        except (ValueError, RuntimeError) as err:  # bad input or a bound reached: report it, run the others
            print(f"dfloop: {scene.source}: {err}", file=sys.stderr)
            failed.append(str(scene.source))
    if failed:
        print(f"dfloop: {len(failed)} of {len(args.scenes)} scenes failed: {', '.join(map(str, failed))}",
              file=sys.stderr)
        return 1
    return 0


def _list() -> int:
    from .scene import shipped_scenes
    from .scene.load import read_toml

    scenes = shipped_scenes()
    width = max((len(name) for name in scenes), default=0)
    for name, path in scenes.items():
        title = read_toml(path).get("scene", {}).get("title", "")
        print(f"{name:<{width}}  {title}")
    return 0


def _cache(args: argparse.Namespace) -> int:
    from .cache_admin import cache_info, clear_cache

    if args.action == "info":
        print(repr(cache_info()))
        return 0
    removed = clear_cache(stale=args.stale)
    print(f"removed {len(removed)} {'stale ' if args.stale else ''}files "
          f"({sum(f.size for f in removed) / 2**20:.1f} MiB) from {cache_info().directory}")
    return 0


def main(argv: list[str] | None = None) -> int:
    try:
        return _main(argv)
    except BrokenPipeError:  # `dfloop scene-keys | head`: the reader left; stop quietly
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1


def _main(argv: list[str] | None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if args.version:
        from . import __version__

        print(f"dfloop {__version__}")
        return 0
    if args.command == "run":
        return _run(args)
    if args.command == "list":
        return _list()
    if args.command == "scene-keys":
        from .scene import scene_reference

        sys.stdout.write(scene_reference())
        return 0
    if args.command == "cache":
        return _cache(args)
    parser.print_help()
    return 2


if __name__ == "__main__":
    sys.exit(main())
