"""gyrocal: gyro calibration-procedure orchestrator.

How the package is assembled: the product folders at the repository root
(models/, instruments/, orchestrator/, reports/) are installed as
subpackages of this namespace by pyproject.toml's package-dir mapping, so
``gyrocal.models.noise`` is the file ``models/noise.py``. This folder holds
only the version, the exit codes (errors.py) and the command line (cli.py).
The layering (errors ← models ← instruments ← orchestrator, reports ← cli) is
checked by tests/test_layout.py.
"""

__version__ = "0.1.0"
