"""``bladetwin`` command line: one sub-command group per stage (docs/design.md §7).

Each group lives in its own ``bladetwin.cli_<group>`` module exposing ``register(subparsers)``; this
module only wires them together, so stages can grow without touching each other. :func:`main` imports only the
module of the command it runs (the others are listed from :data:`bladetwin.cli_commands.COMMANDS`): their
numerics would take 4-6 s to import, before ``bladetwin --help`` or ``bladetwin lab simulate`` could answer.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
import zipfile
from collections.abc import Sequence

from .cli_commands import COMMANDS
from .user_warnings import install as install_warnings

__all__ = ["main", "build_parser", "error_message"]


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The command line's parser.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments it will parse. Given, only the command they name gets its options (its module imported);
        every other command is listed with its one-line help and no options. Default: every command in full.
    """
    parser = argparse.ArgumentParser(
        prog="bladetwin",
        description="Contact-mistuning identification in bladed disks (EMA front end, ROM back end).",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    wanted = None if argv is None else _command_named(argv)
    for name, (module, help_line) in COMMANDS.items():
        if argv is None or name == wanted:
            importlib.import_module(f"bladetwin.{module}").register(sub)
        else:
            sub.add_parser(name, help=help_line)
    return parser


def _command_named(argv: Sequence[str]) -> str | None:
    """The command ``argv`` runs: its first word that is not an option (the top level's take no value)."""
    return next((a for a in argv if not a.startswith("-")), None)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(argv)
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
