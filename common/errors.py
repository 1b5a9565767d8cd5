"""The package's single exception root and its branches.

Every error panostereo raises on purpose derives from :class:`PanoError`, so a
shell can map it to one clear line and a non-zero exit code. Always chain the
cause: ``raise ConfigError(...) from err``.
"""

from __future__ import annotations

__all__ = [
    "CalibrationError",
    "ConfigError",
    "GeometryError",
    "PanoError",
    "SchemaError",
    "SessionError",
    "SourceError",
]


class PanoError(Exception):
    """Root of every error panostereo raises on purpose."""


class ConfigError(PanoError):
    """A configuration file or command-line value is missing or invalid."""


class SchemaError(PanoError):
    """A payload is not a valid message of the expected type.

    Attributes:
        path: where in the message the problem is (``$.blobs[3].bearing_rad``),
            or ``"$"`` when the payload as a whole is unreadable.
    """

    def __init__(self, message: str, path: str = "$") -> None:
        super().__init__(message)
        self.path = path


class SessionError(PanoError):
    """A zenoh session could not be opened or used (router unreachable, bad endpoint)."""


class SourceError(PanoError):
    """A frame source (camera, file, stream, detection file) failed."""


class GeometryError(PanoError):
    """A geometric computation has no valid answer (degenerate rays, too few points)."""


class CalibrationError(GeometryError):
    """A calibration could not be solved from the given data."""
