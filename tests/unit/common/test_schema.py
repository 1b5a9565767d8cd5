"""Schema rules that hold for every wire message (checked by reflection, so new messages are covered too)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import msgspec
import msgspec.inspect as mi
import pytest

from common import schema
from common.schema import MESSAGE_TYPES

SENDER_FIELDS = {"sensor_id", "manager_id", "agent_id"}
UNIT_SUFFIXES = ("_ns", "_s", "_ms", "_rad", "_m", "_m2", "_px", "_mps", "_hz")
UNITLESS_OK = {"confidence", "changed_frac", "unexplained_frac", "zoom", "fps"}
"""Numbers without a unit suffix: fractions, a zoom factor, and frames per second (unit in the name)."""
UNITLESS_LISTS = {"hist", "k", "dist", "r"}
"""Histogram bins and camera matrix coefficients (pixels for K, dimensionless for R and distortion)."""


def walk(info: Any, path: str = "$") -> Iterator[tuple[str, str, Any]]:
    """(path, field name, type) of every field of a struct, recursively."""
    if isinstance(info, mi.StructType):
        for f in info.fields:
            yield f"{path}.{f.name}", f.name, f.type
            yield from walk(f.type, f"{path}.{f.name}")
    elif isinstance(info, mi.UnionType):
        for t in info.types:
            yield from walk(t, path)
    elif isinstance(info, mi.ListType):
        yield from walk(info.item_type, f"{path}[]")


def all_fields() -> list[tuple[str, str, Any]]:
    seen: dict[str, tuple[str, str, Any]] = {}
    for t in MESSAGE_TYPES:
        for path, name, ftype in walk(mi.type_info(t), t.__name__):
            seen[path] = (path, name, ftype)
    return list(seen.values())


FIELDS = all_fields()


@pytest.mark.parametrize("msg_type", MESSAGE_TYPES, ids=lambda t: t.__name__)
def test_every_message_is_frozen_tagged_and_stamped(msg_type: type) -> None:
    info = mi.type_info(msg_type)
    assert isinstance(info, mi.StructType)
    assert msg_type.__struct_config__.frozen  # type: ignore[attr-defined]
    assert info.tag_field == "type"
    assert info.tag == f"pano.{msg_type.__name__}"
    names = [f.name for f in info.fields]
    assert names[0] in SENDER_FIELDS, "the sender id comes first"
    assert {"seq", "stamp_ns"} <= set(names)


def test_tags_are_unique_and_all_structs_tagged() -> None:
    structs = [v for v in vars(schema).values() if isinstance(v, type) and issubclass(v, msgspec.Struct)]
    tags = [mi.type_info(s).tag for s in structs if s.__name__ != "_Msg"]  # type: ignore[attr-defined]
    assert all(tags)
    assert len(tags) == len(set(tags))


@pytest.mark.parametrize(
    ("path", "name", "ftype"),
    [f for f in FIELDS if isinstance(f[2], mi.FloatType)],
    ids=lambda x: x if isinstance(x, str) else "",
)
def test_floats_are_bounded_and_carry_units(path: str, name: str, ftype: Any) -> None:
    lo = ftype.ge if ftype.ge is not None else ftype.gt
    hi = ftype.le if ftype.le is not None else ftype.lt
    assert lo is not None and hi is not None, f"{path} is unbounded (bounds are what make NaN/inf impossible)"
    assert math.isfinite(lo) and math.isfinite(hi)
    assert name.endswith(UNIT_SUFFIXES) or name in UNITLESS_OK, f"{path}: no unit in the name"
    if name.endswith("_rad"):
        assert -2 * math.pi <= lo and hi <= 2 * math.pi, f"{path}: angle range [{lo}, {hi}]"


@pytest.mark.parametrize(
    ("path", "name", "ftype"),
    [f for f in FIELDS if isinstance(f[2], mi.IntType)],
    ids=lambda x: x if isinstance(x, str) else "",
)
def test_ints_are_bounded(path: str, name: str, ftype: Any) -> None:
    assert (ftype.ge is not None or ftype.gt is not None) and (ftype.le is not None or ftype.lt is not None), path
    assert ftype.le is None or ftype.le < 2**63, f"{path} would not fit an int64"


@pytest.mark.parametrize(
    ("path", "name", "ftype"),
    [f for f in FIELDS if isinstance(f[2], (mi.ListType, mi.StrType))],
    ids=lambda x: x if isinstance(x, str) else "",
)
def test_lists_and_strings_have_a_maximum_length(path: str, name: str, ftype: Any) -> None:
    assert ftype.max_length is not None, (
        f"{path} has no max_length: a hostile sender could make us allocate without bound"
    )
    if isinstance(ftype, mi.ListType) and isinstance(ftype.item_type, mi.FloatType):
        assert name.endswith(UNIT_SUFFIXES) or name in UNITLESS_LISTS, f"{path}: no unit in the name"


def test_no_field_type_is_left_open() -> None:
    """Only the kinds of type the checks above understand appear on the wire."""
    allowed = (
        mi.FloatType, mi.IntType, mi.StrType, mi.BoolType, mi.LiteralType, mi.ListType,
        mi.StructType, mi.UnionType, mi.NoneType,
    )  # fmt: skip
    for path, _, ftype in FIELDS:
        assert isinstance(ftype, allowed), f"{path}: {ftype!r}"


def test_limits() -> None:
    assert schema.MAX_BLOBS == 256
    info = mi.type_info(schema.Features)
    assert isinstance(info, mi.StructType)
    blobs = next(f for f in info.fields if f.name == "blobs")
    assert isinstance(blobs.type, mi.ListType) and blobs.type.max_length == schema.MAX_BLOBS


def test_messages_are_immutable() -> None:
    st = schema.PtzState(sensor_id="p1", seq=1, stamp_ns=2, pan_rad=0.0, tilt_rad=0.0, zoom=1.0)
    with pytest.raises(AttributeError):
        st.pan_rad = 1.0  # type: ignore[misc]
