"""Command-line entry point: ``dfloop run|list|scene-keys|cache|warmup``.

``dfloop run <scene> [<scene> ...] [--out DIR] [--quiet]`` runs loop studies: each scene is a TOML file or the
name of a shipped scene (``dfloop list``). Every scene is checked before any runs; a bad one is reported (file,
key, closest valid name) and the others still run; the exit code is 1 if any failed. Progress is shown for the
long stages (a bar on a terminal, plain lines in logs); ``--quiet`` turns it and the stage lines off.

``dfloop cache clear [--stale] [--yes]`` lists the files it would remove (how many, which, their size) and asks
for confirmation; ``--yes`` skips the question, and without it a non-interactive stdin refuses.

Errors of usage or of the environment (an ``--out`` that is a file or cannot be written, a cache that cannot be
listed or cleared, ``DFLOOP_CACHE_DIR`` set but empty, a bad option) print one line ``dfloop: ...`` to stderr and
exit with status 2, without a traceback. A scene that fails exits with status 1 after the others ran.

``dfloop warmup`` compiles the numba code of the solver, the exact engines and the simulations once for this
installation (each also compiles on its first use, saying so on the progress channel).

This module imports nothing heavy at import time, so ``dfloop --help`` answers at once.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

_LISTED = 20  # files listed by `cache clear` before "... and n more"


class CliError(Exception):
    """A usage or environment error: main() prints ``dfloop: <message>`` on one line and returns 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, not argparse's usage block
        raise CliError(f"{message} (see `{self.prog} --help`)")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="dfloop", description="Describing-function limit-cycle studies.")
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
    cache.add_argument("--yes", "-y", action="store_true", help="clear without asking for confirmation")
    sub.add_parser("warmup", help="compile dfloop's numba code now, once for this installation (else on first use)")
    return parser


def _check_cache_env() -> None:
    env = os.environ.get("DFLOOP_CACHE_DIR")
    if env is not None and not env.strip():
        raise CliError(f"DFLOOP_CACHE_DIR is set but empty ({env!r}); set it to a directory, or unset it for the "
                       "default (~/.cache/dfloop, or $XDG_CACHE_HOME/dfloop)")


def _check_out(out: Path) -> None:
    """--out must be a directory dfloop can write in (created if missing), checked before any scene runs."""
    if out.exists() and not out.is_dir():
        raise CliError(f"--out {out}: exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out, prefix=".dfloop-write-check-"):
            pass
    except OSError as exc:
        raise CliError(f"--out {out}: cannot write there ({exc.strerror or exc})") from None


def _run(args: argparse.Namespace) -> int:
    _check_cache_env()
    _check_out(args.out)
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
        except (ValueError, RuntimeError, OSError) as err:  # bad input, a bound reached, a write that failed
            print(f"dfloop: {scene.source}: {' '.join(str(err).split())}", file=sys.stderr)
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


def _mib(files) -> str:
    size = sum(f.size for f in files)
    return f"{size / 2**20:.1f} MiB" if size >= 2**20 else f"{size / 1024:.1f} KiB"


def _confirm(what: str) -> bool:
    """Ask "Remove <what>?" on the terminal; a non-interactive stdin refuses (CliError)."""
    if not (sys.stdin is not None and sys.stdin.isatty()):
        raise CliError(f"cache clear: refused to remove {what} without confirmation (stdin is not a terminal); "
                       "pass --yes")
    try:
        answer = input(f"Remove {what}? [y/N] ")
    except EOFError:
        answer = ""
    return answer.strip().lower() in ("y", "yes")


def _cache(args: argparse.Namespace) -> int:
    _check_cache_env()
    from .cache_admin import cache_info, clear_cache

    try:
        info = cache_info()
        if args.action == "info":
            print(repr(info))
            return 0
        kind = "stale " if args.stale else ""
        files = clear_cache(stale=args.stale, dry_run=True)
    except OSError as exc:
        raise CliError(f"cache {args.action}: {exc}") from None
    if not files:
        print(f"no {kind}files to remove in {info.directory}")
        return 0
    print(f"cache {info.directory}: {len(files)} {kind}file{'s' * (len(files) != 1)} ({_mib(files)}) to remove:")
    for f in files[:_LISTED]:
        mark = " (current)" if f.version == info.current else ""
        print(f"  {f.path.name}  {f.size / 1024:.1f} KiB  {f.version}{mark}")
    if len(files) > _LISTED:
        print(f"  ... and {len(files) - _LISTED} more ({_mib(files[_LISTED:])})")
    if not args.yes and not _confirm(f"these {len(files)} files" if len(files) > 1 else "this file"):
        print("dfloop: cache clear: nothing removed", file=sys.stderr)
        return 1
    errors: list = []
    removed = clear_cache(files=files, errors=errors)
    print(f"removed {len(removed)} {kind}files ({_mib(removed)}) from {info.directory}")
    if errors:
        f, exc = errors[0]
        raise CliError(f"cache clear: could not remove {len(errors)} of {len(files)} files; first: {f.path}: "
                       f"{exc.strerror or exc}")
    return 0


def _warm_impact() -> None:
    from .impact.extract import impact_describing_function_batch

    impact_describing_function_batch(1.0, 1.0, 0.1, 0.5, [50.0], [35.0], transient_periods=None, periods=20)


def _warmup() -> int:
    """Run each entry point that compiles numba code once on a small loop (the compiled code is cached on disk,
    so every later process loads it); prints what was compiled and how long each took."""
    import time

    import control as ct

    import dfloop as df
    from .solve.compiled import warmup

    G, N = ct.tf([5], [1, 1, 0]), df.Backlash(h=1.0)
    smooth = (ct.tf([1], [1, 3, 3, 1]), df.CubicStiffness(10.0, -1.0), (1.633, 1.7321))   # the smooth-loop integrator
    steps = [("solver kernels (predict_limit_cycles)", warmup),
             ("exact engines (exact_cycle)", lambda: (df.exact_cycle(G, N, (1.0103, 1.5914)), df.exact_cycle(*smooth))),
             ("simulation (verify_cycle)", lambda: df.verify_cycle(G, N, (1.0103, 1.5914), periods=10)),
             ("impact kernels (DynamicBacklash tables)", _warm_impact)]
    for what, step in steps:
        t0 = time.perf_counter()
        step()
        print(f"{what}: ready in {time.perf_counter() - t0:.1f} s", flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    """The console script: returns the exit status (0 done, 1 a scene failed or a question was declined,
    2 a usage or environment error, printed as one line on stderr)."""
    try:
        return _main(argv)
    except CliError as err:
        print(f"dfloop: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("dfloop: interrupted", file=sys.stderr)
        return 130
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
    if args.command == "warmup":
        return _warmup()
    parser.print_help()
    return 2


if __name__ == "__main__":
    sys.exit(main())
