"""Materials: isotropic linear elasticity (corotational), with a density."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SceneError


@dataclass(frozen=True)
class Material:
    """Isotropic elastic material.

    Args:
        young_modulus: Young's modulus E (Pa), > 0.
        poisson_ratio: Poisson ratio nu, in (-1, 0.5).
        density: mass density (kg/m^3), >= 0 (0 only for quasi-static scenes).
    """

    young_modulus: float
    poisson_ratio: float
    density: float = 1000.0

    def __post_init__(self) -> None:
        for name in ("young_modulus", "poisson_ratio", "density"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise SceneError(f"Material.{name} must be a finite number, got {value!r}")
        if self.young_modulus <= 0:
            raise SceneError(f"Material.young_modulus must be > 0 Pa, got {self.young_modulus!r}")
        if not -1.0 < self.poisson_ratio < 0.5:
            raise SceneError(f"Material.poisson_ratio must lie in (-1, 0.5), got {self.poisson_ratio!r}")
        if self.density < 0:
            raise SceneError(f"Material.density must be >= 0 kg/m^3, got {self.density!r}")

    @property
    def lame(self) -> tuple[float, float]:
        """Lamé parameters ``(mu, lambda)`` in Pa."""
        E, nu = self.young_modulus, self.poisson_ratio
        return E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
