"""Command-line entry point: ``dfloop run models/<scene>.toml``."""
from __future__ import annotations

import argparse
import sys


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="dfloop", description=__doc__)
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    args = parser.parse_args(argv)
    from . import __version__

    print(f"dfloop {__version__}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
