"""Writing files whole or not at all: every file prbdm writes (data-set parts and manifests,
checkpoints, exported models, reports) goes through :func:`atomic_write`, so that a job that
fails or is killed leaves the old file or none, never half of a new one."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write(path, data: bytes | str, *, make_parents: bool = True,
                 sync: bool = False) -> None:
    """Write ``data`` to ``path`` through a hidden temporary file beside it (``.NAME.*.tmp``),
    then rename it over ``path``.

    The file gets the usual permissions of a new file (0o666 less the umask), not mkstemp's
    0o600. ``make_parents=False``: a missing folder is an error (FileNotFoundError) instead of
    being created. ``sync``: flush the data to disk before the rename (data-set parts, which a
    long run must not lose to a crash of the machine)."""
    path = Path(path)
    if make_parents:
        path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data.encode() if isinstance(data, str) else data)
            if sync:
                fh.flush()
                os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
