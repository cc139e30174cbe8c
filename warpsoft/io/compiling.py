"""Kernel compilation, made visible: Warp compiles a kernel module the first time a step launches
one of its kernels on a device, and keeps the binary in its kernel cache (``wp.config.kernel_cache_dir``),
so a machine compiles each module once. :class:`ModuleLoads` is a Warp logger that counts and
times the modules' loads while it is in use, and can name each compiled one as it finishes.
"""

from __future__ import annotations

import re
from collections.abc import Callable

import warp as wp

LOAD = re.compile(r"Module (\S+)(?: [0-9a-f]+)? load on device '([^']*)'.*? took ([0-9.]+) ms\s*\((compiled|cached)\)")


class ModuleLoads:
    """A Warp logger (``wp.set_logger``) in use inside ``with``: per kind, "compiled" or "cached",
    the modules' loads (``count``) and their time (``ms``); ``compiled`` lists the compiled ones
    as ``(module, seconds)``. ``say``, if given, is called with a line for each compiled module as
    it finishes (a sweep prints it). Warnings and errors go on to the logger it replaced."""

    def __init__(self, say: Callable[[str], None] | None = None):
        self.ms = {"compiled": 0.0, "cached": 0.0}
        self.count = {"compiled": 0, "cached": 0}
        self.compiled: list[tuple[str, float]] = []
        self.say = say
        self._saved = None

    def __enter__(self) -> ModuleLoads:
        self._saved = (wp.get_logger(), wp.config.log_level)
        wp.config.log_level = min(wp.config.log_level, wp.LOG_INFO)  # (module loads are timed at this level)
        wp.set_logger(self)
        return self

    def __exit__(self, *exc) -> None:
        logger, wp.config.log_level = self._saved
        wp.set_logger(logger)

    def debug(self, message: str) -> None:
        pass

    def info(self, message: str) -> None:
        found = LOAD.search(message)
        if not found:
            return
        module, device, ms, kind = found.group(1), found.group(2), float(found.group(3)), found.group(4)
        self.ms[kind] += ms
        self.count[kind] += 1
        if kind == "compiled":
            self.compiled.append((module, ms / 1e3))
            if self.say is not None:
                self.say(f"  compiled kernel module {module} for {device} in {ms / 1e3:.1f} s "
                         f"({len(self.compiled)} so far; kept in Warp's kernel cache)")

    def warning(self, message: str, category=None, stacklevel: int = 1) -> None:
        self._saved[0].warning(message, category, stacklevel + 1)

    def error(self, message: str) -> None:
        self._saved[0].error(message)
