"""Site files: what a site is made of and which processes run it.

A site file (``deploy/sites/*.toml``) describes, for a simulated site, the
world (room, people, lighting) and every camera's true placement; for any
site, the processes to start (``[[process]]``, each with its own config
file) and the router. The simulator and the launcher read it; the
pipeline never sees the simulated truth: sensor nodes get only pixels (or
detection files), and a camera's pose reaches the manager only through its
node's own config (a surveyed pose) or mutual calibration.

Example (abridged)::

    [site]
    name = "demo"
    prefix = "pano"
    fps = 15.0
    duration_s = 60.0
    seed = 1
    router = "tcp/127.0.0.1:7447"

    [world]
    room_x_m = 8.0
    room_y_m = 6.0
    people = 4

    [area]                      # optional: where people can be (a polygon), and its exits
    polygon = [[0.0, 0.0], [8.0, 0.0], [8.0, 6.0], [0.0, 6.0]]

    [[zones]]                   # optional: the floor cut into zones, one manager (and its standbys) each
    name = "west"
    polygon = [[0.0, 0.0], [4.0, 0.0], [4.0, 6.0], [0.0, 6.0]]
    cameras = []                # the cameras that see into it; [] = those of [[camera]] within reach_m of it

    [[camera]]
    id = "pano1"
    kind = "panoramic"
    x_m = 2.0
    y_m = 1.5
    mobile = true
    waypoints = [[2.0, 1.5], [2.5, 1.5]]

    [[process]]
    name = "pano1"
    command = "node"
    config = "../nodes/demo/pano1.toml"
"""

from __future__ import annotations

import itertools
import math
import tomllib
from pathlib import Path
from typing import Annotated, Literal

import msgspec
import numpy as np

from common.area import Area, AreaSpec, overlap_m2
from common.config import ConfigStruct, load_config, resolve_path
from common.errors import ConfigError
from common.keys import DEFAULT_PREFIX, validate_id

__all__ = [
    "CameraSpec",
    "DatasetSpec",
    "LightingSpec",
    "ProcessSpec",
    "SiteConfig",
    "SiteSection",
    "WorldSpec",
    "ZoneSpec",
    "load_site",
    "process_ids",
    "site_sensor_ids",
    "zone_sensor_ids",
]

OVERLAP_M2 = 1e-6
"""Two zones sharing more floor than this overlap (less: rounding along a shared border)."""
PERSON_HEIGHT_RANGE_M = (0.5, 2.5)
"""People's heights a site may declare (``world.person_height_m``) lie within this range."""

Pos = Annotated[float, msgspec.Meta(gt=0.0)]
NonNeg = Annotated[float, msgspec.Meta(ge=0.0)]
Range = Annotated[list[float], msgspec.Meta(min_length=2, max_length=2)]
RGB = Annotated[list[Annotated[int, msgspec.Meta(ge=0, le=255)]], msgspec.Meta(min_length=3, max_length=3)]
XY = Annotated[list[float], msgspec.Meta(min_length=2, max_length=2)]


class SiteSection(ConfigStruct, frozen=True):
    """``[site]``: identity, timing and the router of the site."""

    name: str
    prefix: str = DEFAULT_PREFIX
    fps: Pos = 15.0
    """Frame rate of simulated cameras, and of the ground truth (gt.csv)."""
    duration_s: Pos = 60.0
    """How long ``panostereo demo`` runs the site."""
    seed: int = 1
    router: str = "tcp/127.0.0.1:7447"
    """Endpoint the router listens on and every process connects to."""
    zone_band_m: Annotated[float, msgspec.Meta(gt=0.0, le=100.0)] = 1.0
    """With ``[[zones]]``: half-width of the overlap band along the zones' borders. A person in it is tracked by
    both neighbours and published by the one that had it until they are this far past the border
    (resource_manager/serve/zones.py)."""


class LightingSpec(ConfigStruct, frozen=True):
    """``[world.lighting]``: what the simulated cameras' pixels suffer."""

    noise_sigma: NonNeg = 2.0
    """Std-dev of per-pixel Gaussian sensor noise (grey levels)."""
    drift_amplitude: NonNeg = 0.08
    """Relative amplitude of the slow illumination drift."""
    drift_period_s: Pos = 40.0
    sudden_changes_s: list[NonNeg] = []
    """World times at which the light level jumps."""
    sudden_change_gain: Pos = 1.35
    """Brightness factor applied at each sudden change (alternating up/down)."""
    shadow_gain: Annotated[float, msgspec.Meta(gt=0.0, le=1.0)] = 1.0
    """Brightness of the floor in each person's soft cast shadow, relative to the lit floor (1: no shadows;
    real rooms and squares: 0.5-0.8)."""
    sway_m: NonNeg = 0.0
    """Amplitude of a tall plant by a wall that sways in a draught, a distractor that moves in place like a
    flapping tape or leaves outdoors (0: none)."""


class WorldSpec(ConfigStruct, frozen=True):
    """``[world]``: the simulated room and its people."""

    room_x_m: Pos = 8.0
    room_y_m: Pos = 6.0
    wall_height_m: Pos = 2.8
    people: Annotated[int, msgspec.Meta(ge=0, le=64)] = 4
    person_speed_mps: Range = msgspec.field(default_factory=lambda: [0.5, 1.5])
    person_height_m: Range = msgspec.field(default_factory=lambda: [1.5, 1.9])
    pause_prob: Annotated[float, msgspec.Meta(ge=0.0, le=1.0)] = 0.15
    """Chance that a person pauses at a waypoint."""
    enter_leave: bool = False
    """People enter through and leave by a door instead of staying in the room."""
    margin_m: NonNeg = 0.6
    """People keep at least this far from walls and camera platforms."""
    paths: Literal["random", "rectangle", "line"] = "random"
    """``rectangle``: walk a known rectangular path (the paper's Fig. 7 experiment)."""
    rectangle: Annotated[list[float], msgspec.Meta(min_length=4, max_length=4)] = msgspec.field(
        default_factory=lambda: [2.0, 1.5, 6.0, 4.5]
    )
    """x0, y0, x1, y1 of the rectangular path."""
    lighting: LightingSpec = msgspec.field(default_factory=LightingSpec)


CameraKind = Literal["panoramic", "ptz"]


class CameraSpec(ConfigStruct, frozen=True):
    """``[[camera]]``: one camera's true placement and optics in the simulated world."""

    id: str
    kind: CameraKind = "panoramic"
    x_m: float = 0.0
    y_m: float = 0.0
    height_m: Pos = 1.1
    """Height of the optical centre above the floor."""
    yaw_deg: float = 0.0
    """True heading of the camera's sensor frame in the world."""
    mobile: bool = False
    pose: Literal["surveyed", "mutual"] = "surveyed"
    """How the pipeline learns this camera's pose: from its node config, or by mutual calibration."""
    body_radius_m: NonNeg = 0.18
    """Radius of the white cylinder body (0: no body, e.g. a wall-mounted PTZ)."""
    body_height_m: NonNeg = 0.9
    band_rgb: RGB = msgspec.field(default_factory=lambda: [220, 40, 40])
    """Colour of the marking band that identifies the body to other robots."""
    waypoints: list[XY] = []
    """Mobile: the robot drives through these in a loop (until a goal is given)."""
    max_speed_mps: Pos = 0.5
    image_size: Annotated[list[int], msgspec.Meta(min_length=2, max_length=2)] = msgspec.field(
        default_factory=lambda: [768, 576]
    )
    """Raw image width, height (annular for panoramic, perspective for PTZ)."""
    pano_size: Annotated[list[int], msgspec.Meta(min_length=2, max_length=2)] = msgspec.field(
        default_factory=lambda: [1080, 162]
    )
    """Unwarped cylindrical panorama width, height (panoramic only)."""
    hfov_deg: Annotated[float, msgspec.Meta(gt=1.0, lt=170.0)] = 60.0
    """PTZ: horizontal field of view at zoom 1."""
    pan_deg: float = 0.0
    tilt_deg: float = -10.0
    zoom: Annotated[float, msgspec.Meta(ge=1.0, le=30.0)] = 1.0

    @property
    def yaw_rad(self) -> float:
        return math.radians(self.yaw_deg)


class ProcessSpec(ConfigStruct, frozen=True):
    """``[[process]]``: one OS process of the site."""

    name: str
    command: Literal["node", "manager", "agent"]
    config: str
    """Path of the process's own TOML config, relative to the site file."""
    args: list[str] = []
    """Extra command-line arguments (e.g. an agent subcommand)."""
    host: str = "localhost"
    """Which host runs it (``panostereo up`` starts only processes of ``localhost``/its --host)."""


class DatasetSpec(ConfigStruct, frozen=True):
    """``[dataset]``: a recorded site (detection files) with its ground truth."""

    ground_truth: str = "gt.csv"
    fps: Pos = 2.0
    frames: Annotated[int, msgspec.Meta(ge=0)] = 0
    """Number of frames (0: as many as the detection files hold)."""
    scored_area: Literal["ground_truth", "everywhere"] = "ground_truth"
    """Where tracks are scored: ``ground_truth``, only where the ground truth annotates people (the convex hull
    of its positions, grown by the match distance: a dataset annotated in one camera's view or on a grid says
    nothing about anyone elsewhere), or ``everywhere``."""


class ZoneSpec(ConfigStruct, frozen=True):
    """``[[zones]]``: one part of the floor, fused by the managers of that zone (``[manager] zone`` names it)."""

    name: str
    polygon: list[XY]
    """Corners of a simple polygon (metres, world frame); zones may touch along their borders, never overlap."""
    cameras: list[str] = []
    """The sensor ids whose cameras see into the zone (a camera may serve several zones). Empty: the site's
    ``[[camera]]`` placements within ``reach_m`` of the polygon (inside it, or that close to its border)."""
    reach_m: Pos = 12.0
    """How far a camera sees people well enough to serve the zone."""


class SiteConfig(ConfigStruct, frozen=True):
    """A whole site file."""

    site: SiteSection
    world: WorldSpec = msgspec.field(default_factory=WorldSpec)
    camera: list[CameraSpec] = []
    process: list[ProcessSpec] = []
    dataset: DatasetSpec | None = None
    area: AreaSpec | None = None
    """``[area]``: the floor where people can be and its exits (:mod:`common.area`); None: not declared."""
    zones: list[ZoneSpec] = []
    """``[[zones]]``: the floor cut into zones (none: one manager, or several sharing the whole site)."""
    path: str = ""
    """Where the file was read from (set by :func:`load_site`; not written in the file)."""

    def camera_by_id(self, camera_id: str) -> CameraSpec:
        """The ``[[camera]]`` with this id.

        Raises:
            ConfigError: naming the unknown id and the ones the site has.
        """
        for cam in self.camera:
            if cam.id == camera_id:
                return cam
        known = ", ".join(c.id for c in self.camera) or "none"
        raise ConfigError(f"{self.path or 'site'}: no camera {camera_id!r} (cameras: {known})")

    def resolve(self, relative: str) -> Path:
        """A path written in the site file, resolved against its folder."""
        return resolve_path(self.path or ".", relative)


BUNDLED_SITES = Path(__file__).resolve().parents[1] / "deploy" / "sites"
"""The sites shipped with this installation (``demo``, ``paper1``, ...): a config names one by its bare name."""


def site_file(value: str, config_file: str | Path) -> Path:
    """Where a config's ``site`` value points: a bare name (``"demo"``: no folder, no ``.toml``) is the bundled
    site of that name, so a config copied anywhere (``/etc/panostereo/nodes``) still finds it; anything else is a
    path, relative to the config file's folder.

    Raises:
        ConfigError: a bare name that no bundled site has, naming those that exist.
    """
    if "/" in value or value.endswith(".toml") or value in (".", ".."):
        v = Path(value).expanduser()
        return v if v.is_absolute() else Path(config_file).resolve().parent / v
    bundled = BUNDLED_SITES / f"{value}.toml"
    if not bundled.is_file():
        names = sorted(p.stem for p in BUNDLED_SITES.glob("*.toml"))
        raise ConfigError(f"{config_file}: site {value!r} is no bundled site ({', '.join(names)}) nor a .toml path")
    return bundled


def load_site(path: str | Path) -> SiteConfig:
    """Read and validate a site file.

    Raises:
        ConfigError: for any problem, naming the file and key.
    """
    site = load_config(path, SiteConfig)
    validate_id(site.site.name, f"{path}: site.name")
    seen: set[str] = set()
    for i, cam in enumerate(site.camera):
        validate_id(cam.id, f"{path}: camera[{i}].id")
        if cam.id in seen:
            raise ConfigError(f"{path}: camera id {cam.id!r} appears twice")
        seen.add(cam.id)
        if cam.kind == "ptz" and cam.mobile:
            raise ConfigError(f"{path}: camera {cam.id!r}: a PTZ camera cannot be mobile")
    names: set[str] = set()
    for proc in site.process:
        validate_id(proc.name, f"{path}: process name")
        if proc.name in names:
            raise ConfigError(f"{path}: process name {proc.name!r} appears twice")
        names.add(proc.name)
    if site.area is not None:
        Area.of(site.area, f"{path}: area")
    _check_zones(site, str(path))
    lo, hi = site.world.person_height_m
    if not PERSON_HEIGHT_RANGE_M[0] <= lo <= hi <= PERSON_HEIGHT_RANGE_M[1]:
        raise ConfigError(f"{path}: world.person_height_m must be [low, high] within 0.5-2.5 m, got {[lo, hi]}")
    return msgspec.structs.replace(site, path=str(Path(path)))


def process_ids(site: SiteConfig) -> dict[str, tuple[str, str]]:
    """Process name -> (command, the sensor/manager/agent id its config declares; the name if none).

    Raises:
        ConfigError: a process config is missing or not TOML.
    """
    out: dict[str, tuple[str, str]] = {}
    for proc in site.process:
        path = site.resolve(proc.config)
        try:
            raw = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, tomllib.TOMLDecodeError) as err:
            raise ConfigError(f"{path}: cannot read process config: {err}") from err
        ident = str(raw.get(proc.command, {}).get("id", proc.name))
        out[proc.name] = (proc.command, ident)
    return out


def site_sensor_ids(site: SiteConfig) -> list[str]:
    """The ids of the sensor nodes the site runs (its ``[[process]]`` with ``command = "node"``), sorted.

    These are the sensors a site's manager fuses; whatever else publishes under the site's prefix is refused.
    """
    return sorted({ident for command, ident in process_ids(site).values() if command == "node"})


def _zone_areas(site: SiteConfig, path: str) -> list[Area]:
    """Each zone's polygon as an area; a polygon that is not simple is refused, naming the zone."""
    names: set[str] = set()
    areas = []
    for i, zone in enumerate(site.zones):
        validate_id(zone.name, f"{path}: zones[{i}].name")
        if zone.name in names:
            raise ConfigError(f"{path}: zone name {zone.name!r} appears twice")
        names.add(zone.name)
        areas.append(Area.of(AreaSpec(polygon=zone.polygon), f"{path}: zone {zone.name!r}"))
    return areas


def _seers(site: SiteConfig, zone: ZoneSpec, area: Area) -> list[str]:
    """The ``[[camera]]`` placements within the zone's reach (inside it, or ``reach_m`` from its border)."""
    out = []
    for cam in site.camera:
        xy = np.array([[cam.x_m, cam.y_m]])
        if bool(area.contains(xy)[0]) or float(area.boundary_distance(xy)[0]) <= zone.reach_m:
            out.append(cam.id)
    return out


def _check_zones(site: SiteConfig, path: str) -> None:
    """One clear error for a bad zone definition: a polygon that is not simple, two zones that overlap (one floor,
    one owner), a listed camera that is not one, or a zone no camera sees into."""
    areas = _zone_areas(site, path)
    for i, j in itertools.combinations(range(len(areas)), 2):
        shared = overlap_m2(areas[i], areas[j])
        if shared > OVERLAP_M2:
            raise ConfigError(
                f"{path}: zones {site.zones[i].name!r} and {site.zones[j].name!r} overlap ({shared:.2f} m² of floor "
                "would have two owners): zones may share a border, not floor"
            )
    placed = {cam.id: cam for cam in site.camera}
    for zone, area in zip(site.zones, areas, strict=True):
        if zone.reach_m < site.site.zone_band_m:
            raise ConfigError(
                f"{path}: zone {zone.name!r}: reach_m = {zone.reach_m:g} m is less than [site] zone_band_m = "
                f"{site.site.zone_band_m:g} m: its cameras must see the whole overlap band beyond its border"
            )
        for k, sid in enumerate(zone.cameras):
            validate_id(sid, f"{path}: zone {zone.name!r} cameras[{k}]")
            if sid in placed and sid not in _seers(site, zone, area):
                cam = placed[sid]
                raise ConfigError(
                    f"{path}: zone {zone.name!r} lists camera {sid!r}, which does not see into it (at "
                    f"({cam.x_m:g}, {cam.y_m:g}), farther than reach_m = {zone.reach_m:g} m from the zone)"
                )
        if not (zone.cameras or _seers(site, zone, area)):
            raise ConfigError(
                f"{path}: zone {zone.name!r}: no camera sees into it (no [[camera]] within reach_m = "
                f"{zone.reach_m:g} m of it, and its cameras = [] lists none)"
            )


def zone_sensor_ids(site: SiteConfig, name: str) -> list[str]:
    """The sensor ids a manager of zone ``name`` fuses: the zone's cameras that the site runs as sensor nodes.

    Raises:
        ConfigError: the site has no such zone (naming those it has), or none of the zone's cameras runs here.
    """
    zone = next((z for z in site.zones if z.name == name), None)
    if zone is None:
        known = ", ".join(z.name for z in site.zones) or "none"
        raise ConfigError(f"{site.path or 'site'}: no zone {name!r} (zones: {known})")
    cameras = zone.cameras or _seers(site, zone, Area.of(AreaSpec(polygon=zone.polygon)))
    running = set(site_sensor_ids(site))
    out = sorted(set(cameras) & running)
    if not out:
        raise ConfigError(
            f"{site.path or 'site'}: zone {name!r}: none of its cameras ({', '.join(cameras)}) runs as a sensor node "
            "of the site"
        )
    return out
