"""Site files: a valid site loads with its path, and each malformed one is refused by one ConfigError naming
the file and the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.errors import ConfigError
from common.site import BUNDLED_SITES, load_site, process_ids, site_file, site_sensor_ids

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
