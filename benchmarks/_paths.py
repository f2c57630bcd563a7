"""Import first in every benchmark script (``import _paths``).

The issues name two scripts after the packages they measure (``benchmarks/rom.py``, ``benchmarks/ema.py``).
Python puts a script's folder first on ``sys.path``, so ``import rom`` from any script here would find
``benchmarks/rom.py`` instead of the package. This module puts the repository root in front of that folder,
so the packages win while ``_paths`` itself stays importable (spawned child processes inherit the path and
re-run the script's imports).
"""

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
if str(REPO) not in sys.path[:1]:
    sys.path.insert(0, str(REPO))
