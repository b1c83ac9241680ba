"""Exit codes and the two exceptions every command uses: one home, imported by all layers.

interfaces.md: 0 success · 1 a result failed its acceptance limits · 2 bad
input (file, option, schema), with a message naming the file, line and
field · 3 an instrument or run fault (the run left safe and resumable).
This module imports nothing of ours, so the drivers, the orchestrator and the
reports can all raise these without importing the command line (which would
tie every layer to the one above it).
"""

import errno

EXIT_OK = 0
EXIT_ACCEPTANCE_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_FAULT = 3


class BadInput(Exception):
    """An input problem the user must fix (exit 2); the message names file, line and field.

    The one bad-input base: every error raised on bad input (a procedure, station, model,
    measured log, run folder, key file, option) subclasses it, so the command line maps
    exactly this class to exit 2 and a renamed subclass cannot slip to exit 3.
    """


class RunFaultError(Exception):
    """A condition that ends the run in the safe state (exit 3); the run is resumable."""


#: No room to write: disk full, over quota, or a file-size limit (``ulimit -f``). A run stops
#: as a fault (exit 3), safe and resumable, never as an internal error.
NO_ROOM_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
