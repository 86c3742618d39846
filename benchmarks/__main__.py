"""``python -m benchmarks``: run every benchmark, write one pyperf suite and one table.

See :mod:`benchmarks._gather` for what is run and written, and
``python -m benchmarks --help`` for the options.
"""

from __future__ import annotations

import sys

from ._gather import main

if __name__ == "__main__":
    sys.exit(main())
