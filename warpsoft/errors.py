"""Errors raised by warpsoft. Each message names the component and the offending value."""


class WarpsoftError(Exception):
    """Base class of warpsoft's own errors."""


class SceneError(WarpsoftError, ValueError):
    """A scene, material, region or parameter is invalid."""


class MeshError(SceneError):
    """A mesh cannot be read or is not a valid tetrahedral mesh."""


class SimulationError(WarpsoftError, RuntimeError):
    """A step produced a non-finite state; the state before the step is kept. ``worlds``: the
    worlds of a model of several that failed, when the step could tell (else None)."""

    def __init__(self, message: str, worlds: list[int] | None = None):
        super().__init__(message)
        self.worlds = worlds


class OutputError(WarpsoftError, OSError):
    """An output (the report, the USD) cannot be written (a full disk, a folder taken away); the
    last whole file written before stays in place."""


class UserCodeError(SceneError):
    """The scene's own code (a schedule, a target, a load function) raised an exception; the
    message names the component, the time and the original error (chained as ``__cause__``)."""


def call_user(fn, t: float, what: str):
    """``fn(t)``, the user's code; an exception it raises becomes a :class:`UserCodeError`
    naming ``what`` (e.g. "cable 'c0': its input schedule")."""
    try:
        return fn(t)
    except Exception as exc:  # any error of the user's code: say whose it is
        raise UserCodeError(f"{what} raised {type(exc).__name__}: {exc} (at t = {t:g} s); "
                            "the error is in the scene's code, not in warpsoft") from exc
