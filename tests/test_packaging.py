"""A non-editable install ships every package (an editable one hides a missing entry)."""

import tomllib

from .conftest import ROOT


def test_every_package_folder_is_listed_in_pyproject():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed, dirs = set(config["packages"]), config["package-dir"]
    for name, folder in dirs.items():
        for init in (ROOT / folder).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT / folder)
            package = ".".join([name, *rel.parts])
            if not any(package.startswith(other + ".") and other in dirs for other in dirs if other != name):
                assert package in listed, f"{package} ({init.parent}) is missing from [tool.setuptools] packages"


def test_rooms_keep_their_imports():
    """``scene/`` is host only (no Warp); a kernel never imports ``warpsoft``."""
    import ast

    def imported(path):
        names = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
        return names

    for path in (ROOT / "warpsoft" / "scene").rglob("*.py"):
        assert "warp" not in imported(path), f"{path} imports warp: scene/ is host only"
    for path in (ROOT / "kernels").rglob("*.py"):
        assert "warpsoft" not in imported(path), f"{path} imports warpsoft: kernels stand alone"
