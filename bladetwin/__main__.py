"""``python -m bladetwin``: the same command line as the ``bladetwin`` script (for environments without it on PATH)."""

import sys

from bladetwin.cli import main

if __name__ == "__main__":
    sys.exit(main())
