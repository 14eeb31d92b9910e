"""``python -m aerodelta``: the ``aerodelta`` command line."""

import sys

from aerodelta.cli import main

if __name__ == "__main__":
    sys.exit(main())
