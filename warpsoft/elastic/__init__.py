"""Element models behind one interface: ``linearize`` (rotations or tangents, and the internal
forces at ``q``), ``apply`` (the tangent stiffness product), ``diagonal`` and ``blocks`` (for
preconditioners and assembly) and ``energy``. Corotational linear tetrahedra today; a new
model is one file here, its kernels in ``kernels/elastic/`` and one line in ELEMENT_MODELS.
"""

from __future__ import annotations

from .corotational import Corotational

ELEMENT_MODELS = {"corotational": Corotational}


def element_model(model, name: str = "corotational"):
    """The element model ``name`` of ``model``."""
    return ELEMENT_MODELS[name](model)


__all__ = ["ELEMENT_MODELS", "Corotational", "element_model"]
