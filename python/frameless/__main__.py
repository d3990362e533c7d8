"""``python -m frameless``: the ``frameless`` command."""

import sys

from ._cli import main

sys.exit(main())
