"""Codec: round trips, plain-msgpack readability, precise errors, golden payloads."""

from __future__ import annotations

import math
from pathlib import Path

import msgpack
import msgspec
import msgspec.inspect as mi
import pytest
from hypothesis import given
from hypothesis import strategies as st

from common.codec import MAX_PAYLOAD_BYTES, decode, encode
from common.errors import PanoError, SchemaError
from common.schema import MESSAGE_TYPES, Blob, Features, PtzCommand, SensorInfo, Track
from tests.data.make_golden import GOLDEN, GOLDEN_DIR
from tests.support import message_strategy

TYPES = {t.__name__: t for t in MESSAGE_TYPES}


def _blob(**over: object) -> Blob:
    base: dict[str, object] = {
        "local_id": 1,
        "bearing_rad": 0.5,
        "width_rad": 0.1,
        "top_elev_rad": 0.2,
        "bottom_elev_rad": -0.3,
        "bbox_u_px": 10.0,
        "bbox_v_px": 5.0,
        "bbox_w_px": 20.0,
        "bbox_h_px": 60.0,
    }
    base.update(over)
    return Blob(**base)  # type: ignore[arg-type]


def _features(blobs: list[Blob] | None = None) -> Features:
    return Features(sensor_id="pano1", seq=1, stamp_ns=10, frame_index=1, blobs=blobs or [_blob(), _blob(local_id=2)])


# -- round trip ------------------------------------------------------------------


def _field_names(msg_type: type) -> set[str]:
    info = mi.type_info(msg_type)
    assert isinstance(info, mi.StructType)
    return {f.encode_name for f in info.fields}


@pytest.mark.parametrize("msg_type", MESSAGE_TYPES, ids=lambda t: t.__name__)
@given(data=st.data())
def test_round_trip_and_plain_msgpack_view(msg_type: type, data: st.DataObject) -> None:
    """Every type survives encode/decode, and plain ``msgpack`` sees a dict with the documented field names."""
    msg = data.draw(message_strategy(msg_type))
    wire = encode(msg)
    assert decode(wire, msg_type) == msg
    assert decode(memoryview(wire), msg_type) == msg

    raw = msgpack.unpackb(wire, raw=False)
    assert isinstance(raw, dict)
    assert raw["type"] == f"pano.{msg_type.__name__}"
    assert set(raw) == {"type"} | _field_names(msg_type)
    for name in _field_names(msg_type):
        value = getattr(msg, name)
        if isinstance(value, (int, float, str, bool)) or value is None:
            assert raw[name] == value, name
    # Every message carries its sender, seq and stamp where every consumer expects them.
    assert isinstance(raw["seq"], int)
    assert isinstance(raw["stamp_ns"], int)
    assert {"sensor_id", "manager_id", "agent_id"} & set(raw)


def test_plain_msgpack_nested_blob_fields() -> None:
    raw = msgpack.unpackb(encode(_features()), raw=False)
    blob = raw["blobs"][0]
    assert blob["type"] == "pano.Blob"
    assert blob["bearing_rad"] == 0.5
    assert blob["width_rad"] == 0.1
    assert blob["top_elev_rad"] == 0.2


def test_msgpack_written_by_a_third_party_decodes() -> None:
    """A client with only `msgpack` can send: field names and the type tag are the contract."""
    payload = msgpack.packb(
        {
            "type": "pano.PtzCommand",
            "manager_id": "mgr1",
            "seq": 3,
            "stamp_ns": 99,
            "sensor_id": "ptz1",
            "pan_rad": 1.0,
            "tilt_rad": -0.1,
        }
    )
    cmd = decode(payload, PtzCommand)
    assert (cmd.pan_rad, cmd.tilt_rad, cmd.zoom, cmd.track_id) == (1.0, -0.1, 1.0, "")


def test_unknown_fields_are_ignored_for_forward_compatibility() -> None:
    raw = msgpack.unpackb(encode(_features()), raw=False)
    raw["added_in_v1_1"] = [1, 2, 3]
    assert decode(msgpack.packb(raw), Features) == _features()


# -- errors name the field ----------------------------------------------------------


def _mutated(msg: msgspec.Struct, path: list[str | int], value: object) -> bytes:
    raw = msgpack.unpackb(encode(msg), raw=False)
    cur = raw
    for step in path[:-1]:
        cur = cur[step]
    cur[path[-1]] = value
    return msgpack.packb(raw)


@pytest.mark.parametrize(
    ("path", "value", "want_path"),
    [
        (["blobs", 1, "bearing_rad"], 4.0, "$.blobs[1].bearing_rad"),  # angle out of [-pi, pi]
        (["blobs", 0, "bearing_rad"], math.nan, "$.blobs[0].bearing_rad"),
        (["blobs", 0, "width_rad"], math.inf, "$.blobs[0].width_rad"),
        (["blobs", 0, "top_elev_rad"], -2.0, "$.blobs[0].top_elev_rad"),
        (["blobs", 0, "hist"], [1.5], "$.blobs[0].hist[0]"),
        (["sensor_id"], "Bad/Id", "$.sensor_id"),
        (["sensor_id"], "", "$.sensor_id"),
        (["seq"], -1, "$.seq"),
        (["stamp_ns"], "yesterday", "$.stamp_ns"),
        (["processing_ms"], -0.5, "$.processing_ms"),
        (["state"], "asleep", "$.state"),
        (["blobs", 0, "type"], "pano.Track", "$.blobs[0].type"),
    ],
)
def test_schema_error_names_the_field(path: list[str | int], value: object, want_path: str) -> None:
    with pytest.raises(SchemaError) as info:
        decode(_mutated(_features(), path, value), Features)
    assert info.value.path == want_path
    assert isinstance(info.value, PanoError)
    assert "Features" in str(info.value)


def test_features_from_an_older_node_without_state_read_as_ok() -> None:
    raw = msgpack.unpackb(encode(_features()), raw=False)
    del raw["state"]
    assert decode(msgpack.packb(raw), Features).state == "ok"


def test_missing_required_field() -> None:
    raw = msgpack.unpackb(encode(_features()), raw=False)
    del raw["stamp_ns"]
    with pytest.raises(SchemaError, match="stamp_ns"):
        decode(msgpack.packb(raw), Features)


def test_list_bounds() -> None:
    assert len(decode(encode(_features([_blob()] * 256)), Features).blobs) == 256
    too_many = _mutated(_features(), ["blobs"], [msgpack.unpackb(encode(_blob()))] * 257)
    with pytest.raises(SchemaError) as info:
        decode(too_many, Features)
    assert info.value.path == "$.blobs"


@pytest.mark.parametrize(
    "data",
    [b"", b"\xc1", b"\x81", b"\x93\x01\x02", msgpack.packb([1, 2, 3]), msgpack.packb("Features"), b"\xff" * 10],
    ids=["empty", "reserved", "truncated-map", "truncated-array", "array", "string", "garbage"],
)
def test_unreadable_payloads(data: bytes) -> None:
    with pytest.raises(SchemaError) as info:
        decode(data, Features)
    assert info.value.path.startswith("$")


def test_wrong_message_type_is_rejected() -> None:
    with pytest.raises(SchemaError, match="Track"):
        decode(encode(_features()), Track)


def test_oversize_payload_is_refused_before_decoding() -> None:
    with pytest.raises(SchemaError, match="exceeds"):
        decode(b"\x00" * (MAX_PAYLOAD_BYTES + 1), Features)


def test_deeply_nested_payload_raises_schema_error() -> None:
    nested = b"\x91" * 100_000 + b"\x00"  # 100k nested one-element arrays
    with pytest.raises(SchemaError):
        decode(nested, Features)


def test_union_model_is_tagged() -> None:
    info = GOLDEN["SensorInfo_pinhole"]
    raw = msgpack.unpackb(encode(info), raw=False)  # type: ignore[arg-type]
    assert raw["model"]["type"] == "pano.PinholeModel"
    raw["model"]["type"] = "pano.Unknown"
    with pytest.raises(SchemaError) as err:
        decode(msgpack.packb(raw), SensorInfo)
    assert err.value.path == "$.model.type"


# -- golden payloads ------------------------------------------------------------------


def test_every_message_type_has_a_golden_payload() -> None:
    covered = {type(m).__name__ for m in GOLDEN.values()}
    assert covered == set(TYPES)
    assert {p.stem for p in GOLDEN_DIR.glob("*.msgpack")} == set(GOLDEN)


@pytest.mark.parametrize("name", sorted(GOLDEN))
def test_golden_payload_still_decodes(name: str) -> None:
    want = GOLDEN[name]
    data = (Path(GOLDEN_DIR) / f"{name}.msgpack").read_bytes()
    got = decode(data, type(want))
    assert got == want
    # A plain msgpack reader still sees v1 field names, every one of them still
    # a field of the type (schemas only grow, by appending fields with defaults).
    raw = msgpack.unpackb(data, raw=False)
    assert raw["type"] == f"pano.{type(want).__name__}"
    assert set(raw) - {"type"} <= _field_names(type(want))
    required = {f.encode_name for f in msgspec.structs.fields(type(want)) if f.required}
    assert required <= set(raw)
