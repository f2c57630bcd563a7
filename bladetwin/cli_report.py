"""``bladetwin report``: re-render the HTML report of an output folder of ``bladetwin run``."""

from __future__ import annotations

import argparse

from .cli_commands import command_help
from .report import render_report

__all__ = ["register"]


def register(sub) -> None:
    p = sub.add_parser(
        "report",
        help=command_help("report"),
        description="Re-render the HTML report from the outputs of `bladetwin run` without recomputing: reads "
                    "OUT_DIR/summary.json and the figures and tables it names, and writes one self-contained "
                    "page (images embedded, no JavaScript, no network).",
    )
    p.add_argument("out_dir", nargs="?", default="out/academic", metavar="OUT_DIR",
                   help="output folder of `bladetwin run` (default: %(default)s)")
    p.add_argument("-o", "--output", default=None, metavar="FILE",
                   help="where to write the page (default: the 'report' entry of summary.json, report.html)")
    p.set_defaults(func=_cmd_report)


def _cmd_report(args: argparse.Namespace) -> int:
    path = render_report(args.out_dir, path=args.output)
    print(path)
    return 0
