"""Atomic file writes: a failed write never leaves a half-written file or clobbers a good one."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from uvbake.errors import InputError


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike[str], mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; on success it replaces ``path``, on error it is removed.

    Parameters
    ----------
    path : str or Path
        The file to write; its folder must exist.
    mode : {"w", "wb"}
        Text (UTF-8, ``\\n`` newlines) or binary.

    Yields
    ------
    file object
        Write to it inside the ``with`` block. If the block raises, ``path`` is left as it was.
    """
    if mode not in ("w", "wb"):
        raise InputError(f"atomic_write mode must be 'w' or 'wb', got {mode!r}; pass 'w' or 'wb'")
    path = Path(path)
    folder = path.parent
    if not folder.is_dir():
        raise InputError(f"{path}: folder {folder} does not exist; create it first")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    try:
        kwargs: dict[str, Any] = {"encoding": "utf-8", "newline": "\n"} if mode == "w" else {}
        with os.fdopen(fd, mode, **kwargs) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, _default_mode(path))
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _default_mode(path: Path) -> int:
    """Permissions the file would get from a plain open(): the old file's, else 0o666 minus umask."""
    try:
        return path.stat().st_mode & 0o777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


@contextlib.contextmanager
def staged(finals: list[Path]) -> Iterator[list[Path]]:
    """Yield temporary paths beside each final path; rename all into place only if the block succeeds."""
    temps: list[Path] = []
    try:
        for final in finals:
            fd, name = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".part", dir=final.parent)
            os.close(fd)
            os.unlink(name)  # writers create it themselves (atomically)
            temps.append(Path(name))
        yield temps
        for part, final in zip(temps, finals):
            os.chmod(part, _default_mode(final))
        for part, final in zip(temps, finals):
            os.replace(part, final)
    finally:
        for part in temps:
            with contextlib.suppress(OSError):
                os.unlink(part)


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_write`)."""
    with atomic_write(path, "wb") as f:
        f.write(data)
