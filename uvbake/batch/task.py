"""One asset, on a Dask worker (or in a plain loop): run it in a child process, then commit its files.

Time limits are enforced by running every asset in a child process (``python -m uvbake.batch.child``)
in its own process group, killed with SIGKILL when the limit passes. Why not in the worker: the time
goes into native code (CHOLMOD, Open3D) that no Python-level signal or thread can interrupt, Dask
has no per-task limit that stops a running task, and killing the worker instead would count as a
worker failure against Dask's bounded retries and lose the other work on it. The child also turns a
segfault into one asset's "crashed" record. It costs one interpreter start and the imports (about
2 s here; see the README's batch figures); the child exits when its worker dies.

Commit protocol (so an interrupted batch never leaves something a rerun would trust): the child writes
into ``assets/<id>/.staging-<random>/``; on success the worker removes the old marker, renames every
file into ``assets/<id>/`` and writes the marker ``status.json`` last, atomically, holding the key
and the sha256 of every output. A rerun trusts an asset only if that marker says ``ok``, its key
matches and every listed file still has its recorded hash.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ..io import atomic_write

MARKER = "status.json"
STAGING_PREFIX = ".staging-"
#: summary statuses; every one but these two counts as a failure (exit status 1)
OK_STATUSES = ("done", "cached")


def read_marker(asset_dir, key):
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


def write_marker(asset_dir, marker):
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


def worker_name():
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
                          options=spec["options"])
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


def _run_child(staging: Path, timeout_s):
    """Run the child on ``staging/spec.json``; return (status, one-line error or None)."""
    log = staging / "child.log"
    with open(log, "wb") as out:
        proc = subprocess.Popen([sys.executable, "-m", "uvbake.batch.child", str(staging / "spec.json")],
                                stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True, env=_child_env())
        try:
            code = proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            _kill(proc)
            return "timeout", (f"stopped after its time limit of {timeout_s:g} s; raise --timeout-per-asset "
                               "(or the manifest's timeout_s) if it needs longer")
        except BaseException:          # the worker is being shut down: take the child with us
            _kill(proc)
            raise
    if code == 0 and (staging / "row.json").exists():
        return "done", None
    if (staging / "error.json").exists():
        return "failed", json.loads((staging / "error.json").read_text())["error"]
    tail = [ln for ln in log.read_text(errors="replace").splitlines() if ln.strip()][-1:]
    how = f"killed by {signal.Signals(-code).name}" if code < 0 else f"exit status {code}"
    return "crashed", f"the unwrap process crashed ({how})" + (f": {tail[0].strip()[:300]}" if tail else "")


def _kill(proc):
    try:
        os.killpg(proc.pid, signal.SIGKILL)   # its own process group: the renderer's threads go too
    except ProcessLookupError:
        pass
    proc.wait()


def _child_env():
    env = dict(os.environ)
    # one thread per asset: Dask runs one asset per worker process, and the processes fill the cores
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env.setdefault(name, "1")
    return env
