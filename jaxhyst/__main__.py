"""`python -m jaxhyst ...`: the same command line as the `jaxhyst` script."""

from ._cli import script


if __name__ == "__main__":
    script()
