"""``python -m prrrp``: the same command line as the ``prrrp`` console script."""

from prrrp.cli import console

if __name__ == "__main__":
    console()
