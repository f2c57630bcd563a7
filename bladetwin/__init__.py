"""bladetwin: command line and batch pipeline (floor 3 of the house, docs/design.md §1).

What a script calls, imported on first use (so that ``bladetwin --help`` stays quick)::

    from bladetwin import read_campaign, run_campaigns, write_outputs, render_report
    (res,) = run_campaigns([read_campaign("measurements/academic")])
    write_outputs(res, "out/academic"); render_report("out/academic")
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

#: Public name → the module that owns it.
_OWNERS = {"read_campaign": "bladetwin.campaign", "Campaign": "bladetwin.campaign",
           "CampaignError": "bladetwin.campaign", "load_model": "bladetwin.model",
           "RunOptions": "bladetwin.stages", "RunResult": "bladetwin.stages",
           "run_campaigns": "bladetwin.run", "run_nodes": "bladetwin.run",
           "write_outputs": "bladetwin.outputs", "render_report": "bladetwin.report"}

__all__ = list(_OWNERS)


def __getattr__(name: str):
    if name in _OWNERS:
        return getattr(importlib.import_module(_OWNERS[name]), name)
    raise AttributeError(f"module 'bladetwin' has no attribute {name!r}")
