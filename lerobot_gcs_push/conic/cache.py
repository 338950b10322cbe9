"""Conic data kept on disk between processes (`cached`), so that a fresh planner reads it instead of
compiling; one process builds while the others wait for its file."""

from __future__ import annotations

import contextlib
import hashlib
import os
from collections.abc import Callable
from pathlib import Path

import cvxpy as cp

from lerobot_gcs_push.conic import parametric
from lerobot_gcs_push.conic.parametric import ParametricConic

CACHE_ENV = "LEROBOT_GCS_PUSH_CACHE"  # where conic data is kept between processes ("" : nowhere)


def cached(
    name: str, key: bytes, sources: list[str], build: Callable[[], ParametricConic], check=None
) -> ParametricConic:
    """`build()`'s conic data, kept on disk under `name` and a digest of `key` (the program's data), of
    `sources` (the modules that write it), of this module, of parametric.py (the data's format) and of
    cvxpy's version, so that a fresh planner (every CLI call, every worker process) reads it instead of
    compiling. `check(data)` vets what is
    read (its sizes against the program's); a file that fails it, or cannot be read, is built again."""
    h = hashlib.sha256(key)
    for source in [*sources, __file__, parametric.__file__]:
        h.update(Path(source).read_bytes())
    h.update(cp.__version__.encode())
    root = os.environ[CACHE_ENV] if CACHE_ENV in os.environ else str(Path.home() / ".cache" / "lerobot_gcs_push")
    path = Path(root) / f"{name}-{h.hexdigest()[:24]}.npz" if root else None
    data = _read(path, check)
    if data is not None:
        return data
    # One process builds; the others wait and read its file. The T's compile peaks near 12 GB: two
    # `generate` workers compiling it at once on a fresh machine were killed for memory (24 GiB).
    with _exclusive(path):
        data = _read(path, check)
        if data is not None:
            return data
        data = build()
        if path is not None:
            with contextlib.suppress(OSError):  # a read-only home: no cache, only a slower start
                data.save(path)
    return data


def _read(path: Path | None, check) -> ParametricConic | None:
    """The data kept at `path` if it is there and passes `check`; a file that does not is removed."""
    if path is None or not path.exists():
        return None
    try:
        data = ParametricConic.load(path)
        if check is None or check(data):
            return data
    except Exception:  # truncated by a full disk, say: zipfile and numpy raise errors of their own
        pass
    with contextlib.suppress(OSError):
        path.unlink()
    return None


@contextlib.contextmanager
def _exclusive(path: Path | None):
    """An exclusive lock on `path`'s lock file while the block runs (none without a cache, where locks
    cannot be taken, or where the directory cannot be written)."""
    if path is None:
        yield
        return
    try:
        import fcntl

        path.parent.mkdir(parents=True, exist_ok=True)
        lock = open(path.with_name(path.name + ".lock"), "a")  # noqa: SIM115 (held across the yield)
    except (ImportError, OSError):  # no fcntl (Windows), a read-only cache
        yield
        return
    try:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield
    finally:
        lock.close()  # releases the lock
