"""Site files: a valid site loads with its path, and each malformed one is refused by one ConfigError naming
the file and the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.errors import ConfigError
from common.site import BUNDLED_SITES, load_site, process_ids, site_file, site_sensor_ids, zone_sensor_ids

HEAD = '[site]\nname = "lab"\nseed = 3\n'
CAM = '[[camera]]\nid = "{id}"\nkind = "{kind}"\nmobile = {mobile}\n'


def _write(tmp_path: Path, text: str, name: str = "lab.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_a_site_loads_with_defaults_its_path_and_its_cameras(tmp_path: Path) -> None:
    path = _write(tmp_path, HEAD + "[world]\npeople = 2\n" + CAM.format(id="p1", kind="panoramic", mobile="true"))
    site = load_site(path)
    assert (site.site.name, site.site.seed, site.world.people, site.world.room_x_m) == ("lab", 3, 2, 8.0)
    assert site.path == str(path) and site.camera_by_id("p1").mobile
    with pytest.raises(ConfigError, match=r"lab\.toml: no camera 'p9' \(cameras: p1\)"):
        site.camera_by_id("p9")


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ('[site]\nname = "lab"\nfps = -1\n', "site.fps"),
        ('[site]\nname = "lab"\ncolour = 1\n', "site.colour"),
        ("[world]\npeople = 2\n", "site"),
        ('[site]\nname = "lab lab"\n', "site.name"),
        (HEAD + "[world]\nperson_height_m = [1.9, 1.5]\n", "world.person_height_m"),
        (HEAD + "[world]\npeople = 100\n", "world.people"),
        (HEAD + CAM.format(id="a", kind="panoramic", mobile="false") * 2, "camera id 'a' appears twice"),
        (HEAD + CAM.format(id="z", kind="ptz", mobile="true"), "camera 'z': a PTZ camera cannot be mobile"),
        (HEAD + CAM.format(id="a", kind="fisheye", mobile="false"), "kind"),
        (HEAD + '[[process]]\nname = "n"\ncommand = "node"\nconfig = "x.toml"\n' * 2, "process name 'n'"),
        (HEAD + "[world\n", "lab.toml"),  # not TOML at all
    ],
)
def test_a_malformed_site_gives_one_config_error_naming_the_file_and_key(tmp_path: Path, text: str, key: str) -> None:
    with pytest.raises(ConfigError) as caught:
        load_site(_write(tmp_path, text))
    message = str(caught.value)
    assert "lab.toml" in message and key in message


def test_a_missing_site_file_is_a_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"nope\.toml"):
        load_site(tmp_path / "nope.toml")


def test_processes_name_the_ids_their_configs_declare_and_nodes_are_the_sites_sensors(tmp_path: Path) -> None:
    (tmp_path / "nodes").mkdir()
    _write(tmp_path / "nodes", '[node]\nid = "cam-b"\n', "b.toml")
    _write(tmp_path / "nodes", '[node]\nid = "cam-a"\n', "a.toml")
    _write(tmp_path / "nodes", '[manager]\nid = "mgr"\n', "m.toml")
    _write(tmp_path / "nodes", "[agent]\n", "u.toml")
    procs = "".join(
        f'[[process]]\nname = "{n}"\ncommand = "{c}"\nconfig = "nodes/{f}"\n'
        for n, c, f in [
            ("b", "node", "b.toml"),
            ("a", "node", "a.toml"),
            ("m", "manager", "m.toml"),
            ("u", "agent", "u.toml"),
        ]
    )
    site = load_site(_write(tmp_path, HEAD + procs))
    assert process_ids(site) == {
        "b": ("node", "cam-b"), "a": ("node", "cam-a"), "m": ("manager", "mgr"), "u": ("agent", "u"),
    }  # fmt: skip
    assert site_sensor_ids(site) == ["cam-a", "cam-b"]
    broken = load_site(_write(tmp_path, HEAD + procs.replace("nodes/u.toml", "nodes/gone.toml"), "broken.toml"))
    with pytest.raises(ConfigError, match=r"gone\.toml"):
        process_ids(broken)


def test_a_bundled_site_is_found_by_name_from_a_config_copied_anywhere(tmp_path: Path) -> None:
    """A demo camera config copied to /etc/panostereo/nodes still finds its site; a path stays a path."""
    copied = tmp_path / "etc" / "cam.toml"
    assert site_file("demo", copied) == BUNDLED_SITES / "demo.toml"
    assert load_site(site_file("demo", copied)).site.name == "demo"
    assert site_file("sites/x.toml", copied) == tmp_path / "etc" / "sites" / "x.toml"
    assert site_file("/abs/y.toml", copied) == Path("/abs/y.toml")
    with pytest.raises(ConfigError, match=r"'nowhere' is no bundled site \(.*demo.*\)"):
        site_file("nowhere", copied)


def _hall(tmp_path: Path, zones: str, cams: str = "") -> Path:
    """A 20 x 10 m hall with four cameras, two nodes per half (their configs written), and the given zones."""
    (tmp_path / "nodes").mkdir(exist_ok=True)
    procs = ""
    for i, (x, y) in enumerate([(2.0, 5.0), (8.0, 5.0), (12.0, 5.0), (18.0, 5.0)]):
        _write(tmp_path / "nodes", f'[node]\nid = "c{i}"\n', f"c{i}.toml")
        cams += f'[[camera]]\nid = "c{i}"\nx_m = {x}\ny_m = {y}\n'
        procs += f'[[process]]\nname = "c{i}"\ncommand = "node"\nconfig = "nodes/c{i}.toml"\n'
    return _write(tmp_path, HEAD + cams + procs + zones)


WEST = '[[zones]]\nname = "west"\npolygon = [[0, 0], [10, 0], [10, 10], [0, 10]]\nreach_m = 3.0\n'
EAST = '[[zones]]\nname = "east"\npolygon = [[10, 0], [20, 0], [20, 10], [10, 10]]\nreach_m = 3.0\n'


def test_zones_sharing_a_border_each_fuse_the_cameras_that_see_into_them(tmp_path: Path) -> None:
    site = load_site(_hall(tmp_path, WEST + EAST))
    assert [z.name for z in site.zones] == ["west", "east"]
    # c1 (8 m) and c2 (12 m) are within 3 m of the border: each serves both zones.
    assert zone_sensor_ids(site, "west") == ["c0", "c1", "c2"]
    assert zone_sensor_ids(site, "east") == ["c1", "c2", "c3"]
    listed = load_site(_hall(tmp_path, WEST.replace("reach_m", 'cameras = ["c0"]\nreach_m'), ""))
    assert zone_sensor_ids(listed, "west") == ["c0"]
    with pytest.raises(ConfigError, match=r"no zone 'north' \(zones: west\)"):
        zone_sensor_ids(listed, "north")


@pytest.mark.parametrize(
    ("zones", "message"),
    [
        (
            WEST + EAST.replace("[[10, 0]", "[[9, 0]").replace("[10, 10]]", "[9, 10]]"),
            r"zones 'west' and 'east' overlap \(10.00 m² of floor would have two owners\)",
        ),
        (WEST + WEST.replace('"west"', '"copy"'), r"zones 'west' and 'copy' overlap \(100.00 m²"),
        (
            WEST.replace("[[0, 0], [10, 0], [10, 10], [0, 10]]", "[[0, 0], [10, 10], [10, 0], [0, 10]]"),
            r"zone 'west'.polygon is not simple: its edges 0 and 2 cross",
        ),
        (
            '[[zones]]\nname = "yard"\npolygon = [[40, 40], [50, 40], [50, 50]]\nreach_m = 3.0\n',
            r"zone 'yard': no camera sees into it \(no \[\[camera\]\] within reach_m = 3 m of it",
        ),
        (
            EAST.replace("reach_m", 'cameras = ["c0"]\nreach_m'),
            r"zone 'east' lists camera 'c0', which does not see into it \(at \(2, 5\), farther than reach_m = 3 m",
        ),
        (WEST + WEST, "zone name 'west' appears twice"),
        (
            WEST.replace("reach_m = 3.0", "reach_m = 0.5"),
            r"zone 'west': reach_m = 0.5 m is less than \[site\] zone_band_m = 1 m",
        ),
    ],
)
def test_a_bad_zone_definition_gives_one_clear_error(tmp_path: Path, zones: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        load_site(_hall(tmp_path, zones))
