"""``python -m mdroll ...``: the same command line as ``mdroll ...``."""

import sys

from .cli import main

sys.exit(main())
