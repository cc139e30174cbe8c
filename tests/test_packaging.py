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
