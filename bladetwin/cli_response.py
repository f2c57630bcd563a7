"""``bladetwin response``: the forced response's amplification factors of a finished run, as CSV and PNG.

It reads ``OUT_DIR/summary.json:response`` (written by ``bladetwin run``'s ``response`` node from the full solves
it made) and recomputes nothing: ``response.csv`` (one row per ROM, family and engine order) and ``response.png``
(AF against EO per family, both ROMs, Whitehead's limit) for the EOs and families asked.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from .cli_commands import command_help
from .output_files import save_figure, write_csv
from .outputs_response import RESPONSE_HEADER, plot_response, response_rows
from .stages import names

__all__ = ["register", "read_response", "parse_choice"]


def register(sub) -> None:
    p = sub.add_parser(
        "response", help=command_help("response"),
        description="The mistuning amplification factor per family and engine order of a finished `bladetwin run`, "
                    "for its exported ROM and the paper's: reads OUT_DIR/summary.json, recomputes nothing, writes "
                    "OUT_DIR/response.csv and OUT_DIR/response.png.")
    p.add_argument("out_dir", metavar="OUT_DIR", help="output folder of `bladetwin run`")
    p.add_argument("--eo", default=None, metavar="LIST", help="engine orders, e.g. 0,1,2 (default: all, 0..N/2)")
    p.add_argument("--family", default=None, metavar="LIST", help="families, e.g. 1,2 (default: all the run computed)")
    p.set_defaults(func=_cmd_response)


def read_response(out_dir: str | Path) -> dict:
    """``summary.json:response`` of a run's output folder.

    Raises
    ------
    ValueError
        Where the folder has no summary.json, or its run computed no response (one line, naming the file).
    """
    path = Path(out_dir) / "summary.json"
    if not path.is_file():
        raise ValueError(f"{path}: no summary.json; expected the output folder of a finished `bladetwin run`")
    try:
        block = json.loads(path.read_text(encoding="utf-8")).get(names.RESPONSE)  # the node's block
    except (json.JSONDecodeError, AttributeError) as exc:
        raise ValueError(f"{path}: not a run's summary ({exc})") from None
    if not isinstance(block, dict) or not block.get("roms"):
        raise ValueError(f"{path}: no 'response' block (the run's full-assembly modes and amplification factors); "
                         "expected a run of this version: rerun `bladetwin run` (the store keeps its stages)")
    return block


def parse_choice(text: str | None, allowed: list[int], what: str) -> list[int] | None:
    """The integers of a comma-separated option, each one of ``allowed``; None for the default (all).

    Raises
    ------
    ValueError
        Naming the value and what was expected.
    """
    if text is None:
        return None
    out = []
    for part in text.split(","):
        try:
            v = int(part.strip())
        except ValueError:
            v = None
        if v is None or v not in allowed:
            raise ValueError(f"--{what} {part.strip()!r}: expected one of {', '.join(map(str, allowed))}")
        out.append(v)
    return out


def _cmd_response(args: argparse.Namespace) -> int:
    out = Path(args.out_dir)
    block = read_response(out)
    eos = parse_choice(args.eo, [int(e) for e in block["eos"]], "eo")
    families = parse_choice(args.family, [int(f) for f in block["families"]], "family")
    rows = response_rows(block, eos, families)
    write_csv(out / "response.csv", RESPONSE_HEADER, rows)
    save_figure(lambda: plot_response(block, eos, families), out / "response.png")
    print(f"{out / 'response.csv'}: {len(rows)} rows; {out / 'response.png'}")
    return 0
