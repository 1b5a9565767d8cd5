"""The whole image pipeline on synthetic panoramas: what Features say about the detector's state."""

from __future__ import annotations

import numpy as np

from sensor_node.config import PipelineSettings
from sensor_node.features import PanoramicGeometry
from sensor_node.pipeline import ImagePipeline
from tests.unit.sensor_node.sn_synth import W, backdrop, draw_person, noisy, pano_camera


def _pipeline(*, mobile: bool = False) -> ImagePipeline:
    cam = pano_camera()
    return ImagePipeline(
        "cam", PanoramicGeometry(cam), PipelineSettings(warmup_frames=5, warmup_stride=1), mobile=mobile
    )


def test_features_say_learning_until_the_background_is_learnt_then_ok() -> None:
    rng = np.random.default_rng(2)
    pipe = _pipeline()
    base = backdrop(2)
    states = [
        pipe.process(noisy(base, rng), stamp_ns=round(k * 1e9 / 15), frame_index=k).features.state for k in range(8)
    ]
    assert states[:5] == ["learning"] * 5
    assert states[5:] == ["ok"] * 3
    person = base.copy()
    draw_person(person, 300.0)
    out = pipe.process(noisy(person, rng), stamp_ns=round(9e9 / 15), frame_index=9).features
    assert out.state == "ok" and len(out.blobs) == 1


def test_features_say_moving_while_the_camera_drives() -> None:
    rng = np.random.default_rng(3)
    pipe = _pipeline(mobile=True)
    base = backdrop(3, w=1900)
    for k in range(6):
        pipe.process(noisy(base[:, :W].copy(), rng), stamp_ns=round(k * 1e9 / 15), frame_index=k)
    for k in range(1, 6):  # panning: every frame shifted by 40 columns
        out = pipe.process(
            noisy(base[:, 40 * k : 40 * k + W].copy(), rng), stamp_ns=round((10 + k) * 1e9 / 15), frame_index=10 + k
        )
        assert out.features.state == "moving" and not out.features.blobs
    view = base[:, 200 : 200 + W].copy()
    states = [
        pipe.process(noisy(view, rng), stamp_ns=round((20 + k) * 1e9 / 15), frame_index=20 + k).features.state
        for k in range(8)
    ]
    assert states[0] == "learning" and states[-1] == "ok"
