"""What a body gets when its scene chooses nothing: linear tetrahedra, and a LockingWarning where
they lock (a Poisson ratio of 0.4 or more), so that a bending body is never too stiff silently."""

import warnings

import pytest

import warpsoft as ws
from warpsoft.scene.scene import LOCKING_NU


def beam_scene() -> ws.Scene:
    return ws.Scene("beam", static=True, steps=1)


def test_default_linear_elements_at_silicone_poisson_ratios_warn_of_locking():
    mesh = ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (10, 1, 1))
    with pytest.warns(ws.LockingWarning, match=r"body 'beam': linear tetrahedra \(the default element\) lock at "
                                               r"nu = 0.45.*element='quadratic'"):
        body = beam_scene().add_body("beam", mesh, ws.Material(1e5, 0.45, 1000.0))
    assert body.element == "corotational"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a chosen element, or a ratio where they do not lock: silent
        beam_scene().add_body("beam", mesh, ws.Material(1e5, 0.45, 1000.0), element="corotational")
        beam_scene().add_body("beam", mesh, ws.Material(1e5, 0.45, 1000.0), element="quadratic")
        beam_scene().add_body("beam", mesh, ws.Material(1e5, LOCKING_NU - 0.01, 1000.0))


def test_the_reference_scenes_choose_their_elements(scene_module):
    """Every scene shipped builds without the warning: each one's element is a stated choice."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "scenes"
    for path in sorted([*root.glob("*.py"), *root.glob("validation/*.py")]):
        with warnings.catch_warnings():
            warnings.simplefilter("error", ws.LockingWarning)
            scene_module(str(path.relative_to(root.parent))).build()
