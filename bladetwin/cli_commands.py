"""The command line's commands: the module that registers each one and its line in ``bladetwin --help``.

A light module (no numerics imported): :func:`bladetwin.cli.build_parser` lists every command from here and
imports only the module of the command being run, so ``bladetwin --help`` answers at once.
"""

from __future__ import annotations

__all__ = ["COMMANDS", "command_help"]

#: Command → (module in ``bladetwin``, one-line help), in help order. Each module defines ``register(subparsers)``.
COMMANDS: dict[str, tuple[str, str]] = {
    "run": ("cli_run", "the main job: identify every joint's contact pattern on a campaign, with a report"),
    "report": ("cli_report", "re-render the HTML report from the outputs of `bladetwin run` without recomputing"),
    "response": ("cli_response", "amplification factor per engine order and family of a finished run (CSV, PNG)"),
    "fe": ("cli_fe", "FE models: the academic twin or an imported component; info, modes, plot, export"),
    "ema": ("cli_ema", "experimental modal analysis: fit UFF FRFs, campaign tables"),
    "rom": ("cli_rom", "reduced-order models: build, modes, validate"),
    "lab": ("cli_lab", "virtual test rig: simulate a measurement campaign on a truth twin"),
    "identify": ("cli_identify", "contact-pattern identification: patterns, sensitivity, dataset, predict, validate"),
    "campaign": ("cli_campaign", "campaign manifests: draft campaign.toml from a folder of exports"),
}


def command_help(name: str) -> str:
    """The one-line help of command ``name`` (as ``bladetwin --help`` lists it)."""
    return COMMANDS[name][1]
