"""``python -m warpmesh``: the same as the ``warpmesh`` command."""

import sys

from warpmesh.cli import main

if __name__ == "__main__":
    sys.exit(main())
