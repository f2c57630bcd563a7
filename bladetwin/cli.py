"""``bladetwin`` command line: one sub-command group per stage (docs/design.md §7).

Each group lives in its own ``bladetwin.cli_<group>`` module exposing ``register(subparsers)``; this
module only wires them together, so stages can grow without touching each other.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

__all__ = ["main", "build_parser"]

# Sub-command modules, in help order. Each must define ``register(subparsers) -> None``.
_COMMAND_MODULES = ("cli_run", "cli_fe", "cli_ema", "cli_rom")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bladetwin",
        description="Contact-mistuning identification in bladed disks (EMA front end, ROM back end).",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in _COMMAND_MODULES:
        importlib.import_module(f"bladetwin.{name}").register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(message)s")
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError, KeyError) as exc:
        # User-facing errors: one line, no traceback (the library raises with precise messages).
        print(f"bladetwin: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
