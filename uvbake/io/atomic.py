"""Atomic file writes: a failed write never leaves a half-written file or clobbers a good one."""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO, Any, Literal

from uvbake.cancel import register_temp, unregister_temp
from uvbake.errors import InputError, OutputError


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
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise write_error(path, exc) from None
    register_temp(tmp)
    try:
        kwargs: dict[str, Any] = {"encoding": "utf-8", "newline": "\n"} if mode == "w" else {}
        with os.fdopen(fd, mode, **kwargs) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, _default_mode(path))
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        from uvbake.errors import UvbakeError

        if isinstance(exc, UvbakeError):
            raise
        raise write_error(path, exc) from None   # the user's path, not the temporary file's
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    finally:
        unregister_temp(tmp)


def _default_mode(path: Path) -> int:
    """Permissions the file would get from a plain open(): the old file's, else 0o666 minus umask."""
    try:
        return path.stat().st_mode & 0o777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


class OutputSet:
    """Several output files written all together or not at all.

        outs = OutputSet({"-o": out, "--json": report}, inputs=[mesh_path])   # checks every target now
        outs.write_bytes(out, data)            # to a hidden temporary file beside ``out``
        outs.commit()                          # every file renamed into place, or none on error

    The targets are checked when the set is made, before any work (see :func:`check_targets`).
    Until :meth:`commit`, nothing the user named exists or is changed; any exception (a full disk,
    a signal) removes the temporary files. Every message names the user's path, never a temporary.
    The renames run with SIGINT/SIGTERM held back, so a signal cannot leave half of the set renamed.
    """

    def __init__(self, targets: Any, *, inputs: Iterable[str | os.PathLike[str]] = (), force: bool = False):
        self.flags = check_targets(targets, inputs=inputs, force=force)
        self._temps: dict[Path, Path] = {}

    def __enter__(self) -> OutputSet:
        return self

    def __exit__(self, *exc: object) -> Literal[False]:
        self.discard()
        return False

    def temp_path(self, final: str | os.PathLike[str]) -> Path:
        """A fresh temporary path beside ``final`` (one of the targets) for a writer of its own."""
        final = Path(final)
        if final not in self.flags:
            raise InputError(f"{final} is not one of the outputs checked up front; add it to the set")
        if final in self._temps:
            return self._temps[final]
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".part", dir=final.parent)
            os.close(fd)
        except OSError as exc:
            raise write_error(final, exc, self.flags[final]) from None
        self._temps[final] = Path(tmp)
        register_temp(tmp)
        return self._temps[final]

    def write_bytes(self, final: str | os.PathLike[str], data: bytes) -> None:
        tmp = self.temp_path(final)
        try:
            with open(tmp, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
        except OSError as exc:
            raise write_error(final, exc, self.flags[Path(final)]) from None

    def commit(self) -> list[Path]:
        """Rename every file written so far into place; return their final paths, in order."""
        from uvbake.cancel import check_cancelled, signals_deferred

        check_cancelled()
        done = []
        with signals_deferred():
            for final, tmp in self._temps.items():
                try:
                    os.chmod(tmp, _default_mode(final))
                    os.replace(tmp, final)
                except OSError as exc:
                    raise write_error(final, exc, self.flags[final]) from None
                unregister_temp(tmp)
                done.append(final)
            self._temps = {}
        return done

    def discard(self) -> None:
        """Remove every temporary file (nothing the user named is touched)."""
        for tmp in self._temps.values():
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            unregister_temp(tmp)
        self._temps = {}


def write_error(final: str | os.PathLike[str], exc: OSError, flag: str | None = None) -> OutputError:
    """An :class:`~uvbake.errors.OutputError` naming the user's path (never the temporary file)."""
    what = f"{flag} {final}" if flag else str(final)
    if exc.errno == errno.ENOSPC:
        reason = "no space left on device; free some space or write to another disk"
    elif exc.errno == errno.EDQUOT:
        reason = "disk quota exceeded; free some space or write elsewhere"
    elif exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        reason = f"{exc.strerror.lower() if exc.strerror else 'not permitted'}; check the folder's permissions"
    else:
        reason = f"{(exc.strerror or type(exc).__name__).lower()}; choose another path"
    err = OutputError(f"cannot write {what}: {reason}")
    err.errno = exc.errno
    return err


def check_targets(targets: Any, *, inputs: Iterable[str | os.PathLike[str]] = (),
                  force: bool = False) -> dict[Path, str | None]:
    """Check output paths before any work; return ``{Path: flag}``.

    Parameters
    ----------
    targets : dict {flag or parameter name: path} or iterable of paths (or of (name, path) pairs)
        The name is how the user gave the path (``--json``, ``path=``), used in messages.
    inputs : iterable of paths
        Files no output may replace.
    force : bool
        Replace read-only files (otherwise refused).

    Raises
    ------
    InputError
        A folder is missing or is a file, a target is a folder, the input, read-only, given twice,
        or the folder does not let us create files.
    """
    out: dict[Path, str | None] = {}
    seen: dict[str, str] = {}
    ins = [Path(p) for p in inputs]
    for flag, path in _target_pairs(targets):
        what = f"{flag} {path}" if flag else str(path)
        _check_folder(path, what)
        for src in ins:
            if path.exists() and src.exists() and os.path.samefile(path, src):
                raise InputError(f"output {what} is the input {src}; choose another output path")
        key = os.path.realpath(path)
        if key in seen:
            raise InputError(f"outputs {seen[key]} and {what} are the same file; give them different names")
        seen[key] = what
        if path.exists():
            _check_replaceable(path, what, force)
        _check_creatable(path, what)
        out[path] = flag
    return out


def _target_pairs(targets: Any) -> list[tuple[Any, Path]]:
    """``(name or None, Path)`` for every target of :func:`check_targets`."""
    if isinstance(targets, dict):
        return [(name, Path(p)) for name, p in targets.items()]
    return [(t[0], Path(t[1])) if isinstance(t, tuple) else (None, Path(t)) for t in targets]


def _check_folder(path: Path, what: str) -> None:
    """The target names a file whose folder exists (no path component on the way is a file)."""
    folder = path.parent
    if path.name in ("", ".", ".."):
        raise InputError(f"output {what} is a folder; give a file name")
    probe = folder
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise InputError(f"output {what}: {probe} is a file, not a folder; choose another path")
    if not folder.is_dir():
        raise InputError(f"output {what}: folder {folder} does not exist; create it or choose another path")
    if path.is_dir():
        raise InputError(f"output {what} is a folder; give a file name")


def _check_replaceable(path: Path, what: str, force: bool) -> None:
    """An existing target may be replaced: writable (or ``force``), not immutable or append-only."""
    if not force and not (path.stat().st_mode & 0o222):
        raise InputError(f"output {what} is read-only; pass --force (force=True) to replace it, "
                         "or choose another path")
    try:  # an immutable or append-only file refuses even root; opening changes nothing
        os.close(os.open(path, os.O_WRONLY | os.O_APPEND))
    except PermissionError as exc:
        if exc.errno == errno.EPERM or not force:
            raise InputError(f"output {what} cannot be replaced ({(exc.strerror or 'not permitted').lower()}: immutable, "
                             "append-only or not ours); choose another path") from None


def _check_creatable(path: Path, what: str) -> None:
    """The target's folder lets us create (and remove) a file."""
    folder = path.parent
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=folder)
        os.close(fd)
        os.unlink(tmp)
    except OSError as exc:
        raise InputError(f"output {what}: cannot create files in {folder} "
                         f"({(exc.strerror or str(exc)).lower()}); choose another folder") from None


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_write`)."""
    with atomic_write(path, "wb") as f:
        f.write(data)
