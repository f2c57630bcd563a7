"""``bladetwin`` command line: one sub-command group per stage (docs/design.md §7).

Each group lives in its own ``bladetwin.cli_<group>`` module exposing ``register(subparsers)``; this
module only wires them together, so stages can grow without touching each other.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
import zipfile

from .user_warnings import install as install_warnings

__all__ = ["main", "build_parser", "error_message"]

# Sub-command modules, in help order. Each must define ``register(subparsers) -> None``.
_COMMAND_MODULES = ("cli_run", "cli_report", "cli_response", "cli_fe", "cli_ema", "cli_rom", "cli_lab", "cli_identify",
                    "cli_campaign")


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
    install_warnings()  # every warning a command does not record itself: one line on stderr, no source line
    try:
        return int(args.func(args) or 0)
    except (ValueError, OSError, KeyError, zipfile.BadZipFile, MemoryError) as exc:
        # User-facing errors: one line, exit code 2, no traceback. The libraries raise EMAError / ROMError
        # (ValueError subclasses) with messages written for users; the others come from the OS or numpy.
        print(f"bladetwin: error: {error_message(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        # every finished stage is in the store (atomic entries): the same command resumes from there
        print("bladetwin: interrupted; run the same command again to resume from the stages already stored",
              file=sys.stderr)
        return 130


def error_message(exc: BaseException) -> str:
    """One line for the user: the library's message, an OS error with its file, a KeyError without quotes."""
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}"
    elif isinstance(exc, KeyError) and len(exc.args) == 1 and isinstance(exc.args[0], str):
        text = exc.args[0]  # str(KeyError) adds repr quotes
    elif isinstance(exc, MemoryError):
        text = f"out of memory{': ' + str(exc) if str(exc) else ''} (ask for less: a lower --order, fewer modes)"
    else:
        text = str(exc) or type(exc).__name__
    return " ".join(text.split())


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
