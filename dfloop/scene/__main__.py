"""``python -m dfloop.scene --reference``: print the scene reference page (docs/scenes.md)."""
import argparse
import sys

from .reference import scene_reference


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m dfloop.scene", description=__doc__)
    parser.add_argument("--reference", action="store_true", help="print the reference page (markdown)")
    args = parser.parse_args(argv)
    if not args.reference:
        parser.print_help()
        return 2
    sys.stdout.write(scene_reference())
    return 0


if __name__ == "__main__":
    sys.exit(main())
