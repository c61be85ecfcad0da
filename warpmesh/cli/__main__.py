"""``python -m warpmesh.cli``: the same as the ``warpmesh`` command."""

import sys

from warpmesh.cli.commands import main

sys.exit(main())
