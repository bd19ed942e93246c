"""`python -m jaxhyst ...`: the same command line as the `jaxhyst` script."""

import sys

from ._cli import main


if __name__ == "__main__":
    sys.exit(main())
