"""``bladetwin lab``: the virtual test rig (``lab simulate``: a whole campaign from a truth twin, docs/campaign.md;
``lab response-truth``: the forced response's truth added to a campaign written before it existed)."""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from typing import TYPE_CHECKING

from .cli_commands import command_help
from .util import print_json

if TYPE_CHECKING:
    from lab.campaign import CampaignSpec

__all__ = ["register", "parse_known", "parse_coherence", "spec_from_args", "spec_from_command"]


def register(sub) -> None:
    lab = sub.add_parser("lab", help=command_help("lab"),
                         description="Simulate hammer tests and film scans on a truth twin of the academic bladed "
                                     "disk (docs/campaign.md).")
    lsub = lab.add_subparsers(dest="lab_command", metavar="SUBCOMMAND")
    lsub.required = True
    p = lsub.add_parser("simulate", help="write a virtual campaign (UFF files, film scans, manifest, truth)")
    _add_simulate_arguments(p)
    p.add_argument("--json", action="store_true", help="print {campaign, n_files, truth} as JSON")
    p.set_defaults(func=_cmd_simulate)
    r = lsub.add_parser("response-truth", help="add the forced response's truth (truth/response_modes.npz) to a "
                                                "virtual campaign written before it existed",
                        description="Rebuild a virtual campaign's truth twin from its manifest's generated_by "
                                    "command, check it against truth/truth.json, and write the mistuned and tuned "
                                    "truth's full-assembly modes at the blade points (lab.truth_response; about "
                                    "two full-assembly solves).")
    r.add_argument("campaign", metavar="CAMPAIGN_DIR", help="a campaign folder written by `bladetwin lab simulate`")
    r.set_defaults(func=_cmd_response_truth)


def _add_simulate_arguments(p: argparse.ArgumentParser) -> None:
    """The settings of ``lab simulate`` (also what :func:`spec_from_command` reads back)."""
    p.add_argument("--out", default="measurements/virtual", help="campaign folder to create (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="random seed; the same seed gives the same campaign")
    p.add_argument("--blades", type=int, default=None, help="number of blades (default: the academic twin's)")
    p.add_argument("--grid", default=None, metavar="ROWSxCOLS", help="contact grid per flank (default: the twin's)")
    p.add_argument("--level", default="default", choices=["coarse", "default", "fine"],
                   help="mesh level of the twin (default: %(default)s; coarse is for tests)")
    p.add_argument("--known", default=None, metavar="J,J,...",
                   help="filmed (known) joints, 1-based, e.g. 3,7,10,14,17 (default: up to 5 spread evenly)")
    p.add_argument("--realism", default="realistic", choices=["realistic", "ideal"],
                   help="the truth twin: a specimen and test that differ from the model as real ones do "
                        "(default), or the model's own parts, for tests that isolate one stage (docs/twin.md)")
    p.add_argument("--coherence", default="all", metavar="TYPES",
                   help="test types whose UFF files carry the hammer test's coherence beside the FRFs (it adds "
                        "half a file's size): all (default), none, or a comma list of blade, disk, d1b, assembly")
    p.add_argument("--name", default=None, help="campaign name in the manifest (default: the folder name)")


def parse_coherence(text: str) -> tuple[str, ...]:
    """``--coherence d1b,assembly`` → ("d1b", "assembly"); ``all`` and ``none`` as named."""
    from lab.campaign import TEST_TYPES

    words = tuple(t for t in text.replace(" ", "").split(",") if t)
    if words == ("all",):
        return TEST_TYPES
    if words == ("none",):
        return ()
    bad = [w for w in words if w not in TEST_TYPES]
    if bad or not words:
        raise ValueError(f"--coherence {text!r}: expected all, none, or a comma list of {', '.join(TEST_TYPES)}")
    return words


def parse_known(text: str | None) -> tuple[int, ...] | None:
    """``--known 3,7,10`` → (3, 7, 10); range checks happen against the blade count later."""
    if text is None:
        return None
    try:
        return tuple(int(t) for t in text.replace(" ", "").split(",") if t)
    except ValueError:
        raise ValueError(f"--known takes joint numbers separated by commas, e.g. 3,7,10; got {text!r}") from None


def spec_from_args(args: argparse.Namespace) -> CampaignSpec:
    """The :class:`lab.campaign.CampaignSpec` of parsed ``lab simulate`` arguments, every setting checked.

    Raises
    ------
    ValueError
        One line naming a bad seed, blade count, grid, level or known joints.
    """
    from pathlib import Path

    from lab.campaign import CampaignSpec

    from .cli_fe import parse_grid

    out = Path(args.out)
    if args.seed < 0:
        raise ValueError(f"--seed {args.seed}: expected a non-negative integer")
    kw = {}
    if args.blades is not None:
        kw["n_blades"] = args.blades
    grid = parse_grid(args.grid)
    if grid is not None:
        kw["grid"] = grid
    spec = CampaignSpec(seed=args.seed, level=args.level, known_joints=parse_known(args.known),
                        name=args.name or out.name, realism=args.realism,
                        coherence=parse_coherence(args.coherence), **kw)
    # Every argument is checked before minutes of simulation (blade count, grid, level, known joints).
    spec.model_params()
    spec.known()
    return spec


class _CommandParser(argparse.ArgumentParser):
    """An argument parser whose errors are ValueErrors (one line), not an exit."""

    def error(self, message: str):
        raise ValueError(message)


def spec_from_command(command: str) -> CampaignSpec:
    """The :class:`lab.campaign.CampaignSpec` of a ``bladetwin lab simulate ...`` command, as a campaign's
    ``[campaign] generated_by`` records it (``CampaignSpec.command``), read with ``lab simulate``'s own parser.

    Raises
    ------
    ValueError
        If it is not such a command, has an argument ``lab simulate`` does not take, or a bad setting.
    """
    try:
        words = shlex.split(command)
    except ValueError as exc:
        raise ValueError(f"generated_by {command!r}: unreadable command ({exc})") from None
    if words[:3] != ["bladetwin", "lab", "simulate"]:
        raise ValueError(f"generated_by {command!r}: expected a `bladetwin lab simulate` command")
    parser = _CommandParser(prog="bladetwin lab simulate", add_help=False)
    _add_simulate_arguments(parser)
    try:
        args = parser.parse_args(words[3:])
    except ValueError as exc:
        raise ValueError(f"generated_by {command!r}: {exc}") from None
    return spec_from_args(args)


def _progress():
    t0 = time.perf_counter()

    def progress(msg: str) -> None:
        print(f"… [{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    return progress


def _cmd_simulate(args: argparse.Namespace) -> int:
    from pathlib import Path

    from lab.campaign import simulate_campaign

    spec = spec_from_args(args)
    info = simulate_campaign(spec, Path(args.out), progress=_progress())
    if args.json:
        print_json(info.to_dict())
    else:
        print(f"wrote {info.n_files} files to {info.campaign} (truth: {info.truth})")
    return 0


def _cmd_response_truth(args: argparse.Namespace) -> int:
    from lab.truth_response import add_response_truth

    t0 = time.perf_counter()
    path = add_response_truth(args.campaign, progress=_progress(), spec_of=spec_from_command)
    size = path.stat().st_size
    print(f"wrote {path} ({size / 1024:.0f} KiB, {time.perf_counter() - t0:.0f} s); the rebuilt twin matches "
          "truth.json")
    return 0
