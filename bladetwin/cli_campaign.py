"""``bladetwin campaign init``: draft a folder's ``campaign.toml`` from its UFF files and film scans."""

from __future__ import annotations

import argparse
from pathlib import Path

from .cli_commands import command_help

__all__ = ["register"]

_DESCRIPTION = (
    "Draft FOLDER/campaign.toml from the files under FOLDER: one [[tests]] entry per UFF file (*.uff, *.unv), "
    "its test type (blade, disk, d1b, assembly) and d1b joint guessed from its DOF set and the numbering of "
    "docs/campaign.md, a blade test's blade from its file name; one [[films]] entry per image (png, jpg, tif, "
    "bmp), joint and flank from the image's PNG text fields or its file name; and [campaign] with n_blades, "
    "the filmed joints and the FRF units. Fields nothing tells (grid, the model, the films' metadata) hold "
    "placeholders under a FILL IN comment, which `bladetwin run` refuses in one line until they are given; "
    "unsure guesses carry a GUESS comment. A virtual campaign's truth/ folder is skipped. A folder with no UFF "
    "file, or with one that no numbering rule explains, is refused in one line naming it. Prints one line per "
    "test type with its count, and the draft's path."
)


def register(sub) -> None:
    camp = sub.add_parser("campaign", help=command_help("campaign"),
                          description="Campaign manifests (docs/campaign.md).")
    csub = camp.add_subparsers(dest="campaign_command", metavar="SUBCOMMAND")
    csub.required = True
    p = csub.add_parser("init", help="draft FOLDER/campaign.toml from its UFF files and film scans",
                        description=_DESCRIPTION)
    p.add_argument("folder", metavar="FOLDER", help="the campaign folder: UFF files and film scans, in any sub-folders")
    p.add_argument("--numbering", default=None, metavar="KEY=VALUE,...",
                   help="the lab's node numbering where it differs from docs/campaign.md's: stride (blade point p "
                        "of slot s is node blade_offset + stride·s + p; default 1000), blade_offset (default 0), "
                        "disk_offset (the disk point of sector s is node disk_offset + s; default 0), e.g. "
                        "stride=100,disk_offset=50")
    p.add_argument("--force", action="store_true", help="replace an existing campaign.toml")
    p.set_defaults(func=_cmd_init)


def _cmd_init(args: argparse.Namespace) -> int:
    from .campaign_draft import check_target, draft_campaign, summary_lines, write_draft
    from .campaign_init import parse_numbering

    numbering = parse_numbering(args.numbering)  # both checked before any file is read
    check_target(Path(args.folder), args.force)
    draft = draft_campaign(args.folder, numbering)
    path = write_draft(draft, force=args.force)
    for line in summary_lines(draft, path):
        print(line)
    return 0
