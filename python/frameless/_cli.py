"""The ``frameless`` command: the package's console script and ``python -m frameless``
run the binary's own command-line code, compiled into the extension."""

import signal
import sys
from typing import Optional, Sequence

from . import _frameless


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run ``frameless`` with ``argv`` (default: this process's arguments); its exit
    status."""
    args = sys.argv[1:] if argv is None else list(argv)
    # As the binary: Ctrl-C ends the command at once (Python would only note it, and
    # the command never returns to Python while it runs).
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    # Both write to the same streams: what Python buffered goes first.
    sys.stdout.flush()
    sys.stderr.flush()
    return _frameless.main(["frameless", *args])
