"""MessagePack encode/decode of the wire schema, with validation.

``decode`` never raises anything but :class:`~common.errors.SchemaError`
for bad input: truncated bytes, wrong types, out-of-range or non-finite
numbers, oversize lists, unknown tags. The error names the field path.
"""

from __future__ import annotations

import re
from collections.abc import Hashable
from functools import cache
from typing import Any, TypeVar, cast

import msgspec

from common.errors import SchemaError

__all__ = ["MAX_PAYLOAD_BYTES", "decode", "encode"]

T = TypeVar("T")

MAX_PAYLOAD_BYTES = 1 << 20
"""Payloads larger than this are refused before decoding (1 MiB)."""

_ENCODER = msgspec.msgpack.Encoder()
_PATH_RE = re.compile(r" - at `(?P<path>[^`]*)`$")


@cache
def _decoder(msg_type: Any) -> msgspec.msgpack.Decoder[Any]:
    return msgspec.msgpack.Decoder(msg_type)


def encode(msg: msgspec.Struct) -> bytes:
    """Serialise one message to MessagePack bytes."""
    return _ENCODER.encode(msg)


def decode(data: bytes | bytearray | memoryview, msg_type: type[T]) -> T:
    """Decode and validate ``data`` as ``msg_type``.

    Raises:
        SchemaError: with ``.path`` naming the offending field.
    """
    if len(data) > MAX_PAYLOAD_BYTES:
        raise SchemaError(f"payload of {len(data)} bytes exceeds the {MAX_PAYLOAD_BYTES}-byte limit", "$")
    try:
        decoder: msgspec.msgpack.Decoder[Any] = _decoder(cast(Hashable, msg_type))
        return cast(T, decoder.decode(data))
    except msgspec.ValidationError as err:
        text = str(err)
        m = _PATH_RE.search(text)
        path = m.group("path") if m else "$"
        raise SchemaError(f"{getattr(msg_type, '__name__', msg_type)}: {text}", path) from err
    except (msgspec.DecodeError, ValueError, TypeError, OverflowError, RecursionError) as err:
        raise SchemaError(f"{getattr(msg_type, '__name__', msg_type)}: unreadable payload: {err}", "$") from err
