"""Errors raised for bad input: each names where the input came from, the field and why.

A user who hands reachwise a broken robot file, task file or point cloud must learn
which file, which entry and what is wrong, never read a numpy traceback.
"""

from __future__ import annotations


class ReachwiseError(ValueError):
    """Base class of every error reachwise raises on purpose."""


class InputError(ReachwiseError):
    """Bad input: ``source`` (a file path or an argument name), ``field`` and ``reason``."""

    def __init__(self, source: str, field: str, reason: str) -> None:
        self.source = source
        self.field = field
        self.reason = reason
        where = f"{source}: {field}" if field else source
        super().__init__(f"{where}: {reason}")


class RobotFileError(InputError):
    """A robot file (YAML or URDF) or robot definition is invalid."""


class CloudError(InputError):
    """A point cloud or point-cloud file is invalid."""


class TaskError(InputError):
    """A task file or task definition is invalid."""
