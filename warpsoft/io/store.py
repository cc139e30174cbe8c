"""A sweep's folder: finished designs appended as they finish, resumed by the same command,
guarded against a second writer and against mixing two sweeps.

Files in the folder:

- ``designs.jsonl``: one line per finished design (its index, parameters, status, steps,
  seconds, metrics, error), appended and flushed to disk when its batch ends; a line cut by a
  kill is ignored when read back;
- ``sweep.json``: the sweeps the folder holds, each a fingerprint of its command (the scene
  file's path and text, its designs, steps and options) with its first design index and count;
- ``.lock``: the process writing the folder (its pid), while it runs.

The same command again skips the designs it finished (a resume); another command is refused
unless it asks to append (its designs take the next indices) or to overwrite (the folder's
results are cleared first).
"""

from __future__ import annotations

import hashlib
import json
import os
from contextlib import contextmanager
from pathlib import Path

from ..errors import SceneError
from .atomic import write_whole

DONE = ("completed", "failed", "invalid")  # a design with one of these is finished: a resume skips it


def fingerprint(scene_file: str | Path, designs: list[dict], steps: int | None, options: dict) -> str:
    """What makes two sweep commands the same: the scene file (path and text), the complete
    designs, the steps and the simulator's options."""
    path = Path(scene_file).resolve()
    text = {"scene": str(path), "source": hashlib.sha256(path.read_bytes()).hexdigest(), "designs": designs,
            "steps": steps, "options": options}
    return hashlib.sha256(json.dumps(text, sort_keys=True, default=repr).encode()).hexdigest()


@contextmanager
def folder_lock(out: Path):
    """Hold ``out/.lock`` while the body runs: another live process holding it is an error
    naming it; a lock left by a process that is gone is taken over."""
    lock = out / ".lock"
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
            break
        except FileExistsError:
            try:
                pid = int(lock.read_text().strip() or "0")
            except (OSError, ValueError):
                pid = 0
            if pid and _alive(pid):
                raise SceneError(f"sweep: {out} is being written by process {pid} (its lock: {lock}); wait for it, "
                                 "or give another --out") from None
            lock.unlink(missing_ok=True)  # its writer is gone
    else:
        raise SceneError(f"sweep: cannot take the lock {lock}")
    try:
        os.write(fd, str(os.getpid()).encode())
        os.close(fd)
        yield
    finally:
        lock.unlink(missing_ok=True)


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's live process
        return True
    return True


class ResultStore:
    """The rows of a sweep folder (see the module doc).

    Args:
        out: the folder.
        key: this command's :func:`fingerprint`.
        count: its number of designs.
        append: add this command's designs after another sweep's in the folder.
        overwrite: clear the folder's results first.

    Attributes:
        first: index of this command's first design in the folder's table.
        rows: every finished design's row, by index (the folder's other sweeps' included).
    """

    def __init__(self, out: Path, key: str, count: int, append: bool = False, overwrite: bool = False):
        self.out, self.lines = out, out / "designs.jsonl"
        manifest = out / "sweep.json"
        if overwrite:
            for name in ("designs.jsonl", "sweep.json", "results.csv", "results.parquet"):
                (out / name).unlink(missing_ok=True)
        parts = json.loads(manifest.read_text())["sweeps"] if manifest.exists() else []
        if not parts and not self.lines.exists() and (out / "results.csv").exists():
            raise SceneError(f"sweep: {out} holds a results.csv this sweep did not write; give --overwrite to "
                             "replace it, or another --out")
        mine = next((p for p in parts if p["fingerprint"] == key), None)
        if mine is None:
            if parts and not append:
                raise SceneError(f"sweep: {out} holds the results of another sweep (another scene, designs, steps "
                                 "or options); give --append to add these designs to its table, --overwrite to "
                                 "start again, or another --out")
            mine = {"fingerprint": key, "first": sum(p["count"] for p in parts), "count": count}
            parts.append(mine)
            write_whole(manifest, lambda tmp: tmp.write_text(json.dumps({"sweeps": parts}, indent=1)))
        self.first = mine["first"]
        self.rows = self._read()

    def _read(self) -> dict[int, dict]:
        rows = {}
        if self.lines.exists():
            for line in self.lines.read_text().splitlines():
                try:
                    row = json.loads(line)
                except json.JSONDecodeError:  # a line cut by a kill: that design runs again
                    continue
                if row.get("status") in DONE:
                    rows[int(row["design"])] = row
        return rows

    def done(self, k: int) -> dict | None:
        """The row of this command's design ``k`` if it finished already, else None."""
        return self.rows.get(self.first + k)

    def add(self, rows: list[dict]) -> None:
        """Append finished designs' rows (``design`` already the folder's index), flushed to disk."""
        with open(self.lines, "a") as f:
            for row in rows:
                f.write(json.dumps(row, default=float) + "\n")
                self.rows[int(row["design"])] = row
            f.flush()
            os.fsync(f.fileno())

    def table(self) -> list[dict]:
        """Every finished design's row, by index, flat (design, status, steps, seconds, its
        parameters, its metrics, error), as the results table holds them."""
        return [{"design": r["design"], "status": r["status"], "steps": r["steps"], "seconds": r["seconds"]}
                | r["params"] | r["metrics"] | {"error": r["error"] or ""} for _, r in sorted(self.rows.items())]
