"""Shared fixtures: CPU device, scene-file loading, reference-mesh folder."""

from pathlib import Path

import pytest
import warp as wp

import warpsoft as ws  # noqa: F401  (sets Warp's log level)
from warpsoft.io.runner import load_scene_module

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT.parent / "shared" / "reference" / "softrobots"


def pytest_configure(config):
    wp.init()
    wp.set_device("cpu")


@pytest.fixture(scope="session")
def scene_module():
    """Import a scene file by its path relative to the repository root."""
    cache = {}

    def load(rel: str):
        if rel not in cache:
            cache[rel] = load_scene_module(ROOT / rel)
        return cache[rel]

    return load


@pytest.fixture(scope="session")
def reference_dir() -> Path:
    if not REFERENCE.is_dir():
        pytest.skip("../shared/reference/softrobots is not beside the checkout")
    return REFERENCE
