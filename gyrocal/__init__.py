"""gyrocal: gyro calibration-procedure orchestrator.

The product folders at the repository root (models/, instruments/,
orchestrator/, reports/) are installed as subpackages of this namespace.
"""

__version__ = "0.1.0"
