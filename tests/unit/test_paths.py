from pathlib import Path

import pytest

from plem.core.paths import BUILTIN_PACKAGES_DIR, find_package, resolve_resource, search_roots
from plem.errors import PackageNotFoundError


def _package(folder: Path, name: str) -> Path:
    path = folder / name
    path.mkdir(parents=True)
    (path / "package.xml").write_text(f"<package><name>{name}</name></package>")
    return path


def test_search_order(tmp_path: Path):
    env = {"PLEM_PACKAGE_PATH": f"{tmp_path / 'a'}:{tmp_path / 'b'}", "AMENT_PREFIX_PATH": str(tmp_path / "install")}
    assert search_roots(env) == [tmp_path / "a", tmp_path / "b", tmp_path / "install" / "share", BUILTIN_PACKAGES_DIR]


def test_earlier_root_shadows_later_and_entry_may_be_a_package(tmp_path: Path):
    first = _package(tmp_path / "a", "robot_description")
    _package(tmp_path / "install" / "share", "robot_description")
    direct = _package(tmp_path / "solo", "solo_description")
    env = {"PLEM_PACKAGE_PATH": f"{tmp_path / 'a'}:{direct}", "AMENT_PREFIX_PATH": str(tmp_path / "install")}
    assert find_package("robot_description", env) == first
    assert find_package("solo_description", env) == direct


def test_ament_share(tmp_path: Path):
    share_pkg = _package(tmp_path / "install" / "share", "arm_description")
    assert find_package("arm_description", {"AMENT_PREFIX_PATH": str(tmp_path / "install")}) == share_pkg


def test_missing_package_says_where_it_looked(tmp_path: Path):
    with pytest.raises(PackageNotFoundError) as error:
        find_package("ghost_description", {"PLEM_PACKAGE_PATH": str(tmp_path)})
    assert str(tmp_path) in error.value.why and "PLEM_PACKAGE_PATH" in error.value.how


def test_resolve_resource_forms(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    package = _package(tmp_path / "ws", "arm_description")
    (package / "config").mkdir()
    (package / "config" / "x.yaml").write_text("a: 1\n")
    monkeypatch.setenv("PLEM_PACKAGE_PATH", str(tmp_path / "ws"))
    monkeypatch.chdir(tmp_path)
    assert resolve_resource("arm_description/config/x.yaml") == package / "config" / "x.yaml"
    assert resolve_resource(package / "config" / "x.yaml") == package / "config" / "x.yaml"
    (tmp_path / "arm_description" / "config").mkdir(parents=True)
    (tmp_path / "arm_description" / "config" / "x.yaml").write_text("a: 2\n")
    assert resolve_resource("arm_description/config/x.yaml") == tmp_path / "arm_description" / "config" / "x.yaml"
