"""Outputs written whole: to a temporary file beside the target, then renamed over it, so that a
reader, a full disk or a kill mid-write never leaves half a file, only the last whole one."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path


def write_whole(path: Path, write: Callable[[Path], object], tmp: Path | None = None) -> Path:
    """``write(tmp)``, then ``tmp`` renamed over ``path`` (``tmp``: ``PATH.tmp`` beside it unless
    given); the temporary is removed when the write or the rename fails, and the error goes on."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp") if tmp is None else tmp
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path
