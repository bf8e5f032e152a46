"""One asset, on a Dask worker (or in a plain loop): run it in a child process, then commit its files.

Time limits are enforced by running every asset in a child process (forked by a pre-imported
:mod:`uvbake.batch.zygote`, one per worker thread) in its own session, killed with SIGKILL when the
limit passes. Why not in the worker: the time
goes into native code (CHOLMOD, Open3D) that no Python-level signal or thread can interrupt, Dask
has no per-task limit that stops a running task, and killing the worker instead would count as a
worker failure against Dask's bounded retries and lose the other work on it. The child also turns a
segfault into one asset's "crashed" record. Forking from the zygote avoids paying an interpreter
start and the imports per asset; the child exits when its worker dies.

Commit protocol (so an interrupted batch never leaves something a rerun would trust): the child writes
into ``assets/<id>/.staging-<random>/``; on success the worker removes the old marker, renames every
file into ``assets/<id>/`` and writes the marker ``status.json`` last, atomically, holding the key
and the sha256 of every output. A rerun trusts an asset only if that marker says ``ok``, its key
matches and every listed file still has its recorded hash.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import select
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from uvbake.io.atomic import atomic_write

MARKER = "status.json"
STAGING_PREFIX = ".staging-"
#: summary statuses; every one but these two counts as a failure (exit status 1)
OK_STATUSES = ("done", "cached")


def read_marker(asset_dir: str | os.PathLike[str], key: str) -> dict[str, Any] | None:
    """The marker of a completed asset whose outputs are intact and whose key is ``key``, else None."""
    path = Path(asset_dir) / MARKER
    try:
        marker = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if marker.get("status") != "ok" or marker.get("key") != key:
        return None
    for name, digest in marker.get("outputs", {}).items():
        if _sha256(Path(asset_dir) / name) != digest:
            return None
    return marker


def write_marker(asset_dir: str | os.PathLike[str], marker: dict[str, Any]) -> None:
    with atomic_write(Path(asset_dir) / MARKER) as fh:
        json.dump(marker, fh, indent=1, sort_keys=True)


def _sha256(path):
    h = hashlib.sha256()
    try:
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return None
    return h.hexdigest()


def worker_name() -> str:
    """The Dask worker's address when running on one, else ``host:pid``."""
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return f"{socket.gethostname()}:{os.getpid()}"


def process(spec: dict) -> dict:
    """Unwrap one asset within its time limit and commit its outputs; return its summary row.

    ``spec``: ``id``, ``input``, ``asset_dir``, ``key``, ``options`` (see :func:`uvbake.batch.run`),
    ``timeout_s``. Never raises for a problem of the asset itself: that is the row's status and error.
    """
    t0 = time.perf_counter()
    asset_dir = Path(spec["asset_dir"])
    asset_dir.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=asset_dir))
    row = dict(asset=spec["id"], input=spec["input"], key=spec["key"], worker=worker_name())
    try:
        child_spec = dict(input=spec["input"], staging=str(staging), stem=Path(spec["input"]).stem,
                          options=spec["options"], watch_pid=os.getpid())
        (staging / "spec.json").write_text(json.dumps(child_spec))
        status, error = _run_child(staging, spec["timeout_s"])
        if status == "done":
            numbers = json.loads((staging / "row.json").read_text())
            row.update(numbers)
            if not numbers["valid"] and spec["options"]["unwrap"]["guarantee"]:
                status, error = "invalid", "the atlas still has flipped or overlapping triangles (see report.json)"
            outputs = list(numbers["files"]) + ["report.json"] + \
                [numbers[k] for k in ("preview", "atlas") if numbers.get(k)]
            (asset_dir / MARKER).unlink(missing_ok=True)       # no marker while files are replaced
            for name in outputs:
                os.replace(staging / name, asset_dir / name)
            row["t_asset_s"] = time.perf_counter() - t0
            row.update(status=status, error=error)
            write_marker(asset_dir, dict(status="ok" if status == "done" else status, key=spec["key"],
                                         row=row, outputs={n: _sha256(asset_dir / n) for n in outputs}))
        else:
            row.update(status=status, error=error, t_asset_s=time.perf_counter() - t0)
            (asset_dir / MARKER).unlink(missing_ok=True)
            write_marker(asset_dir, dict(status=status, key=spec["key"], row=row, outputs={}))
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return row


def _run_child(staging: Path, timeout_s: float) -> tuple[str, str | None]:
    """Run the asset of ``staging/spec.json`` in a child process; return (status, one-line error or None)."""
    log = staging / "child.log"
    _, code = _ZYGOTES.run(staging / "spec.json", timeout_s)
    if code is None:
        return "timeout", (f"stopped after its time limit of {timeout_s:g} s; raise --timeout-per-asset "
                           "(or the manifest's timeout_s) if it needs longer")
    if code == 0 and (staging / "row.json").exists():
        return "done", None
    if (staging / "error.json").exists():
        return "failed", json.loads((staging / "error.json").read_text())["error"]
    tail = [ln for ln in log.read_text(errors="replace").splitlines() if ln.strip()][-1:] if log.exists() else []
    how = f"killed by {signal.Signals(-code).name}" if code < 0 else f"exit status {code}"
    return "crashed", f"the unwrap process crashed ({how})" + (f": {tail[0].strip()[:300]}" if tail else "")


class _Zygotes:
    """One pre-imported zygote (:mod:`uvbake.batch.zygote`) per worker thread, started on first use."""

    def __init__(self):
        self._local = threading.local()

    def _get(self):
        z = getattr(self._local, "proc", None)
        if z is None or z.poll() is not None:
            z = subprocess.Popen([sys.executable, "-m", "uvbake.batch.zygote"], stdin=subprocess.PIPE,
                                 stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, bufsize=0,
                                 start_new_session=True, env=_child_env())
            self._local.proc, self._local.buf = z, b""
        return z

    def run(self, spec_path, timeout_s):
        """(pid, exit code or None when the time limit stopped it); negative codes are signals."""
        z = self._get()
        try:
            z.stdin.write(f"{spec_path}\n".encode())
            pid = int(self._line(z, 120.0).split()[1])       # the imports happen before the first answer
        except (OSError, ValueError, IndexError, TimeoutError) as exc:
            self._discard(z)
            raise RuntimeError(f"the uvbake zygote process failed to start an asset ({exc})") from None
        try:
            status = int(self._line(z, timeout_s).split()[1])
        except TimeoutError:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(pid, signal.SIGKILL)     # its own session: whatever it started goes too
            self._line(z, 60.0)                   # the zygote reaps it
            return pid, None
        except BaseException:                     # the worker is shutting down: take the child with us
            with contextlib.suppress(ProcessLookupError):
                os.killpg(pid, signal.SIGKILL)
            self._discard(z)
            raise
        return pid, os.waitstatus_to_exitcode(status)

    def _line(self, z, timeout_s):
        """The zygote's next answer line, waiting at most ``timeout_s`` (the asset's time limit)."""
        fd, deadline = z.stdout.fileno(), time.monotonic() + timeout_s
        while b"\n" not in self._local.buf:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not select.select([fd], [], [], remaining)[0]:
                raise TimeoutError
            chunk = os.read(fd, 4096)
            if not chunk:
                raise OSError("the zygote exited")
            self._local.buf += chunk
        line, _, self._local.buf = self._local.buf.partition(b"\n")
        return line.decode()

    def _discard(self, z):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(z.pid, signal.SIGKILL)
        z.wait()
        self._local.proc = None


_ZYGOTES = _Zygotes()


def _child_env():
    env = dict(os.environ)
    # one thread per asset: Dask runs one asset per worker process, and the processes fill the cores
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env.setdefault(name, "1")
    return env
