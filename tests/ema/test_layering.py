"""ema is floor 1: importing it pulls in neither rom, identify, lab nor bladetwin."""

import subprocess
import sys
from pathlib import Path


def test_ema_imports_no_upper_floor():
    code = (
        "import sys, ema, ema.plots; "
        "print([m for m in ('rom', 'identify', 'lab', 'bladetwin') if m in sys.modules])"
    )
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
