"""``python -m mdroll ...``: the same command line as ``mdroll ...``."""

import sys

from .cli import main

if __name__ == "__main__":  # not when a spawned worker process imports this module
    sys.exit(main())
