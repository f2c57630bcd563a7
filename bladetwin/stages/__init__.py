"""The stages of ``bladetwin run`` as a graph of named nodes, a content-addressed store and a runner (design §2.1).

- :mod:`~bladetwin.stages.graph`: :class:`Node` (a plain function with declared inputs) and :class:`Pipeline`;
- :mod:`~bladetwin.stages.names`: the catalog, every node and source name declared once;
- :mod:`~bladetwin.stages.store`: :class:`Store`, each node's output under the hash of its inputs;
- :mod:`~bladetwin.stages.runner`: :class:`Runner`, the graph by its dependencies on worker processes;
- :mod:`~bladetwin.stages.campaign_graph`: the nodes of one campaign (EMA, reductions, films, sensitivity,
  dataset, bias, k-NN, refinement, full solves, validation), in the modules beside it.

No node draws or writes files: :mod:`bladetwin.outputs` does, from :class:`RunResult`.
"""

from .campaign_graph import RunOptions, campaign_pipeline, campaign_sources
from .graph import Node, Pipeline
from .result import PAPER_TABLE8, RunResult, gather
from .runner import Results, Runner, Source
from .store import Store

__all__ = ["Node", "Pipeline", "Store", "Runner", "Results", "Source", "RunOptions", "RunResult", "PAPER_TABLE8",
           "campaign_pipeline", "campaign_sources", "gather"]
