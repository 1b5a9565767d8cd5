"""One exception root: every deliberate error is a PanoError, so a shell can map it to one line and an exit code."""

from __future__ import annotations

import pytest

from common.errors import (
    CalibrationError,
    ConfigError,
    GeometryError,
    PanoError,
    SchemaError,
    SessionError,
    SourceError,
)


@pytest.mark.parametrize(
    ("cls", "parent"),
    [
        (ConfigError, PanoError),
        (SchemaError, PanoError),
        (SessionError, PanoError),
        (SourceError, PanoError),
        (GeometryError, PanoError),
        (CalibrationError, GeometryError),
    ],
)
def test_every_error_derives_from_the_root(cls: type[PanoError], parent: type[PanoError]) -> None:
    assert issubclass(cls, parent) and issubclass(cls, PanoError)
    assert not issubclass(PanoError, cls)


def test_schema_error_says_where_in_the_message() -> None:
    assert SchemaError("bad").path == "$"
    err = SchemaError("bearing_rad must be finite", path="$.blobs[3].bearing_rad")
    assert err.path == "$.blobs[3].bearing_rad" and str(err) == "bearing_rad must be finite"
