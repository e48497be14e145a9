"""``python -m prrrp``: the same command line as the ``prrrp`` console script."""

import sys

from prrrp.cli import main

if __name__ == "__main__":
    sys.exit(main())
