"""Errors raised by warpsoft. Each message names the component and the offending value."""


class WarpsoftError(Exception):
    """Base class of warpsoft's own errors."""


class SceneError(WarpsoftError, ValueError):
    """A scene, material, region or parameter is invalid."""


class MeshError(SceneError):
    """A mesh cannot be read or is not a valid tetrahedral mesh."""


class SimulationError(WarpsoftError, RuntimeError):
    """A step produced a non-finite state; the state before the step is kept."""
