"""Where people can be: a site's floor area (a simple polygon) and the parts of its boundary where people come
and go (exits), with the plane geometry the tracker and the plots need.

A site file states them as facts of the site, in metres in the site's world frame::

    [area]
    polygon = [[-3.0, -9.0], [9.0, -9.0], [9.0, 27.0], [-3.0, 27.0]]
    exits = [[[9.0, 0.0], [9.0, 4.0]]]   # optional: a door on the east wall (segments or polygons)

With no ``exits``, people may come and go anywhere on the boundary; ``exits = []`` says nobody does (a closed
room).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Protocol

import msgspec
import numpy as np

from common.arrays import BoolArray, FloatArray
from common.config import ConfigStruct
from common.errors import ConfigError

__all__ = ["Area", "AreaSpec", "Floor", "NearZone", "overlap_m2", "rectangle", "segments_intersect", "signed_depth"]

XY = Annotated[list[float], msgspec.Meta(min_length=2, max_length=2)]
POLYGON_CORNERS = 3
"""The fewest corners of a polygon."""
SEGMENT_POINTS = 2
"""An exit of two points is a segment; of more, a polygon."""
MIN_AREA_M2 = 1e-6
"""A polygon enclosing less than this has no inside."""
GRID_M = 0.25
"""The grid step at which the extent of a :class:`NearZone` is measured."""


class AreaSpec(ConfigStruct, frozen=True):
    """``[area]``: the floor where people can be, and where they come and go."""

    polygon: list[XY]
    """Corners of a simple polygon (at least 3, in order, metres, world frame)."""
    exits: list[list[XY]] | None = None
    """Where people come and go: each a segment (2 points) along the boundary or a polygon (3 or more) around a
    door. Not given: anywhere on the boundary; ``[]``: nowhere (a closed room: nobody leaves it)."""


def segments_intersect(p1: FloatArray, p2: FloatArray, q1: FloatArray, q2: FloatArray) -> bool:
    """Whether the closed segments p1-p2 and q1-q2 share a point."""

    def orient(a: FloatArray, b: FloatArray, c: FloatArray) -> float:
        return float((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))

    def on(a: FloatArray, b: FloatArray, c: FloatArray) -> bool:
        return min(a[0], b[0]) <= c[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= c[1] <= max(a[1], b[1])

    d1, d2 = orient(q1, q2, p1), orient(q1, q2, p2)
    d3, d4 = orient(p1, p2, q1), orient(p1, p2, q2)
    if ((d1 > 0 > d2) or (d1 < 0 < d2)) and ((d3 > 0 > d4) or (d3 < 0 < d4)):
        return True
    return (
        (d1 == 0 and on(q1, q2, p1))
        or (d2 == 0 and on(q1, q2, p2))
        or (d3 == 0 and on(p1, p2, q1))
        or (d4 == 0 and on(p1, p2, q2))
    )


def _edges(points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(k, 2) starts and ends of a closed polygon's edges."""
    return points, np.roll(points, -1, axis=0)


def _segment_distance(xy: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """(n, k) distance of each point ``xy`` (n, 2) to each segment ``a``-``b`` (k, 2)."""
    ab = b - a
    length2 = np.maximum(np.einsum("ki,ki->k", ab, ab), 1e-18)
    ap = xy[:, None, :] - a[None, :, :]
    s = np.clip(np.einsum("nki,ki->nk", ap, ab) / length2, 0.0, 1.0)
    near = a[None, :, :] + s[:, :, None] * ab[None, :, :]
    return np.asarray(np.hypot(*(xy[:, None, :] - near).transpose(2, 0, 1)), dtype=np.float64)


def _inside(xy: FloatArray, points: FloatArray) -> BoolArray:
    """(n,) whether points lie inside a polygon (crossing number; the boundary counts as either)."""
    a, b = _edges(points)
    x, y = xy[:, 0:1], xy[:, 1:2]
    crosses = (a[None, :, 1] > y) != (b[None, :, 1] > y)
    dy = np.where(b[:, 1] == a[:, 1], 1e-300, b[:, 1] - a[:, 1])
    x_at = a[None, :, 0] + (y - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / dy[None, :]
    return np.asarray((crosses & (x < x_at)).sum(axis=1) % 2 == 1, dtype=bool)


@dataclass(frozen=True, slots=True)
class Area:
    """A validated :class:`AreaSpec`, ready for geometry."""

    polygon: FloatArray
    """(k, 2) corners."""
    exit_segments: FloatArray
    """(e, 2, 2) the exits' edges: the whole boundary where no exit is declared."""

    @staticmethod
    def of(spec: AreaSpec, source: str = "area") -> Area:
        """The area of a spec.

        Raises:
            ConfigError: a polygon with fewer than 3 corners, one that crosses itself or encloses nothing, an
                exit with fewer than 2 points, or numbers that are not finite.
        """
        pts = np.asarray(spec.polygon, dtype=np.float64).reshape(-1, 2)
        if len(pts) < POLYGON_CORNERS:
            raise ConfigError(f"{source}.polygon needs at least 3 corners, got {len(pts)}")
        if not np.isfinite(pts).all():
            raise ConfigError(f"{source}.polygon has a corner that is not a finite number: {spec.polygon!r}")
        a, b = _edges(pts)
        k = len(pts)
        for i in range(k):
            for j in range(i + 1, k):
                if j == i + 1 or (i == 0 and j == k - 1):
                    continue  # neighbours share a corner
                if segments_intersect(a[i], b[i], a[j], b[j]):
                    raise ConfigError(
                        f"{source}.polygon is not simple: its edges {i} and {j} cross ({pts[i].tolist()}-"
                        f"{pts[(i + 1) % k].tolist()} and {pts[j].tolist()}-{pts[(j + 1) % k].tolist()})"
                    )
        if abs(_signed_area(pts)) < MIN_AREA_M2:
            raise ConfigError(f"{source}.polygon encloses no area: {spec.polygon!r}")
        segments: list[FloatArray] = []
        for n, ex in enumerate(spec.exits or []):
            e = np.asarray(ex, dtype=np.float64).reshape(-1, 2)
            if len(e) < SEGMENT_POINTS or not np.isfinite(e).all():
                raise ConfigError(f"{source}.exits[{n}] must be 2 points (a segment) or 3 or more (a polygon)")
            ea, eb = (e[:1], e[1:]) if len(e) == SEGMENT_POINTS else _edges(e)
            segments.extend(np.stack([ea, eb], axis=1))
        if spec.exits is None:
            segments = list(np.stack([a, b], axis=1))
        return Area(pts, np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2))

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x0, y0, x1, y1) of the polygon's bounding box."""
        lo, hi = self.polygon.min(axis=0), self.polygon.max(axis=0)
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])

    @property
    def area_m2(self) -> float:
        return abs(_signed_area(self.polygon))

    def contains(self, xy: FloatArray) -> BoolArray:
        """(n,) whether floor points ``xy`` (n, 2) are inside the area."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        return _inside(xy, self.polygon)

    def exit_distance(self, xy: FloatArray) -> FloatArray:
        """(n,) distance (m) of floor points ``xy`` (n, 2) to the nearest exit (infinite where there is none)."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if not len(xy):
            return np.zeros(0)
        if not len(self.exit_segments):
            return np.full(len(xy), np.inf)
        return np.asarray(
            _segment_distance(xy, self.exit_segments[:, 0], self.exit_segments[:, 1]).min(axis=1), dtype=np.float64
        )

    def boundary_distance(self, xy: FloatArray) -> FloatArray:
        """(n,) distance (m) of floor points ``xy`` (n, 2) to the polygon's boundary."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if not len(xy):
            return np.zeros(0)
        a, b = _edges(self.polygon)
        return np.asarray(_segment_distance(xy, a, b).min(axis=1), dtype=np.float64)


class Floor(Protocol):
    """Where a tracker follows people, as its geometry is asked about: an :class:`Area`, or a :class:`NearZone`."""

    @property
    def bounds(self) -> tuple[float, float, float, float]: ...

    @property
    def area_m2(self) -> float: ...

    def contains(self, xy: FloatArray) -> BoolArray: ...

    def exit_distance(self, xy: FloatArray) -> FloatArray: ...

    def boundary_distance(self, xy: FloatArray) -> FloatArray: ...


def signed_depth(area: Area, xy: FloatArray) -> FloatArray:
    """(n,) signed distance (m) of floor points ``xy`` (n, 2) to the area's border: positive inside, negative
    outside."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if not len(xy):
        return np.zeros(0)
    d = area.boundary_distance(xy)
    return np.asarray(np.where(area.contains(xy), d, -d), dtype=np.float64)


class NearZone:
    """The part of a site's area (anywhere, when the site declares none) within ``margin_m`` of a zone: the floor a
    zone manager follows people on. Its border ``margin_m`` outside the zone is an exit (people walk out of what
    this manager follows there, into a neighbour's); the site's exits stay exits.

    Args:
        zone: the zone's polygon.
        margin_m: how far outside the zone people are still followed.
        site: the site's area (None: it declares none).
    """

    def __init__(self, zone: Area, margin_m: float, site: Area | None = None) -> None:
        self.zone, self.margin_m, self.site = zone, margin_m, site
        x0, y0, x1, y1 = zone.bounds
        x0, y0, x1, y1 = x0 - margin_m, y0 - margin_m, x1 + margin_m, y1 + margin_m
        if site is not None:
            sx0, sy0, sx1, sy1 = site.bounds
            x0, y0, x1, y1 = max(x0, sx0), max(y0, sy0), min(x1, sx1), min(y1, sy1)
        self._bounds = (x0, y0, x1, y1)
        gx = np.arange(x0 + GRID_M / 2, x1, GRID_M)
        gy = np.arange(y0 + GRID_M / 2, y1, GRID_M)
        grid = np.stack(np.meshgrid(gx, gy), axis=-1).reshape(-1, 2)
        self._area_m2 = float(self.contains(grid).sum()) * GRID_M * GRID_M if len(grid) else 0.0
        self._edge_points = _offset_contour(zone, margin_m, site)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        return self._bounds

    @property
    def area_m2(self) -> float:
        """Its extent, counted on a ``GRID_M`` grid."""
        return self._area_m2

    def _to_edge(self, xy: FloatArray) -> FloatArray:
        """(n,) signed distance (m) to the contour ``margin_m`` outside the zone: positive within it."""
        return signed_depth(self.zone, xy) + self.margin_m

    def contains(self, xy: FloatArray) -> BoolArray:
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        near = self._to_edge(xy) >= 0.0
        return np.asarray(near if self.site is None else near & self.site.contains(xy), dtype=bool)

    def exit_distance(self, xy: FloatArray) -> FloatArray:
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if self.site is None:  # people come and go anywhere
            return np.zeros(len(xy))
        out = self.site.exit_distance(xy)
        if len(self._edge_points) and len(xy):
            d = np.hypot(xy[:, None, 0] - self._edge_points[None, :, 0], xy[:, None, 1] - self._edge_points[None, :, 1])
            out = np.minimum(out, d.min(axis=1))
        return np.asarray(out, dtype=np.float64)

    def boundary_distance(self, xy: FloatArray) -> FloatArray:
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        edge = np.abs(self._to_edge(xy))
        return np.asarray(edge if self.site is None else np.minimum(edge, self.site.boundary_distance(xy)))


def _offset_contour(zone: Area, margin_m: float, site: Area | None) -> FloatArray:
    """(k, 2) points every ``GRID_M`` / 2 or so along the contour ``margin_m`` outside ``zone`` (its edges moved
    out, its corners rounded), those inside ``site`` only: where people walk out of a :class:`NearZone`."""
    pts = zone.polygon if _signed_area(zone.polygon) > 0 else zone.polygon[::-1]  # counter-clockwise: out is right
    a, b = _edges(pts)
    step = GRID_M / 2
    out = []
    for p, q in zip(a, b, strict=True):
        edge = q - p
        length = float(np.hypot(*edge))
        if length <= 0.0:
            continue
        normal = np.array([edge[1], -edge[0]]) / length
        t = np.linspace(0.0, 1.0, max(2, math.ceil(length / step) + 1))
        out.append(p + t[:, None] * edge + margin_m * normal)
        angles = np.linspace(0.0, 2.0 * math.pi, max(8, math.ceil(2.0 * math.pi * margin_m / step)), endpoint=False)
        out.append(p + margin_m * np.stack([np.cos(angles), np.sin(angles)], axis=1))
    cand = np.concatenate(out) if out else np.zeros((0, 2))
    # Of the moved edges and corner circles, the contour is what lies the margin from the zone, not nearer.
    keep = np.abs(-signed_depth(zone, cand) - margin_m) <= step
    if site is not None:
        keep &= site.contains(cand)
    return np.asarray(cand[keep], dtype=np.float64)


def _triangles(pts: FloatArray) -> list[FloatArray]:
    """A simple polygon cut into triangles (ear clipping), each (3, 2) counter-clockwise."""
    poly = np.asarray(pts if _signed_area(pts) > 0 else pts[::-1], dtype=np.float64)
    out: list[FloatArray] = []
    while len(poly) > POLYGON_CORNERS:
        n = len(poly)
        for i in range(n):
            corners = [(i - 1) % n, i, (i + 1) % n]
            tri = poly[corners]
            if _signed_area(tri) <= 0:
                continue  # a reflex (or flat) corner is no ear
            others = np.delete(poly, corners, axis=0)
            if len(others) and _inside_or_on(others, tri).any():
                continue
            out.append(tri)
            poly = np.delete(poly, i, axis=0)
            break
        else:  # only flat corners left (collinear points): what remains encloses nothing
            return out
    out.append(poly)
    return out


def _inside_or_on(xy: FloatArray, tri: FloatArray) -> BoolArray:
    """(n,) whether points lie in a counter-clockwise triangle, its edges included."""
    a, b = _edges(tri)
    cross = (b[None, :, 0] - a[None, :, 0]) * (xy[:, None, 1] - a[None, :, 1]) - (b[None, :, 1] - a[None, :, 1]) * (
        xy[:, None, 0] - a[None, :, 0]
    )
    return np.asarray((cross >= 0).all(axis=1), dtype=bool)


def _clip(subject: FloatArray, convex: FloatArray) -> FloatArray:
    """The part of polygon ``subject`` inside the counter-clockwise convex polygon ``convex`` (Sutherland-Hodgman)."""
    out = subject
    for a, b in zip(*_edges(convex), strict=True):
        if not len(out):
            break
        side = (b[0] - a[0]) * (out[:, 1] - a[1]) - (b[1] - a[1]) * (out[:, 0] - a[0])
        kept: list[FloatArray] = []
        for i in range(len(out)):
            p, q, sp, sq = out[i], out[(i + 1) % len(out)], side[i], side[(i + 1) % len(out)]
            if sp >= 0:
                kept.append(p)
            if (sp >= 0) != (sq >= 0):
                kept.append(p + (q - p) * (sp / (sp - sq)))
        out = np.array(kept).reshape(-1, 2)
    return out


def overlap_m2(a: Area, b: Area) -> float:
    """The floor area (m²) two areas share: 0 for areas that only touch along a border or at a corner."""
    total = 0.0
    for ta in _triangles(a.polygon):
        for tb in _triangles(b.polygon):
            part = _clip(ta, tb)
            if len(part) >= POLYGON_CORNERS:
                total += abs(_signed_area(part))
    return total


def _signed_area(pts: FloatArray) -> float:
    a, b = _edges(pts)
    return 0.5 * float(np.sum(a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1]))


def rectangle(x0: float, y0: float, x1: float, y1: float) -> AreaSpec:
    """The area spec of an axis-aligned rectangle."""
    if not (math.isfinite(x0) and math.isfinite(y0) and math.isfinite(x1) and math.isfinite(y1)) or not (
        x0 < x1 and y0 < y1
    ):
        raise ConfigError(f"an area rectangle needs X0 < X1 and Y0 < Y1, got {[x0, y0, x1, y1]}")
    return AreaSpec(polygon=[[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
