"""Helpers of the batch tests: small mesh files (good and bad) and a real Dask cluster on 127.0.0.1."""

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from meshgen import bumpy_disk, cone, cut_cylinder, grid, plane

REPO = Path(__file__).resolve().parents[1]


def write_ply(path, V, F):
    """ASCII PLY (hand-written so NaN coordinates can be written as they are)."""
    lines = ["ply", "format ascii 1.0", f"element vertex {len(V)}", "property float x", "property float y",
             "property float z", f"element face {len(F)}", "property list uchar int vertex_indices", "end_header"]
    lines += [f"{x!r} {y!r} {z!r}" for x, y, z in np.asarray(V, float).tolist()]
    lines += [f"3 {a} {b} {c}" for a, b, c in np.asarray(F)]
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)


def good_meshes(folder, n=3):
    """``n`` small valid meshes (a few hundred triangles) with distinct shapes; returns their paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    makers = [lambda: plane(9, 7), lambda: cut_cylinder(14, 5), lambda: cone(14, 5), lambda: bumpy_disk(10),
              lambda: plane(12, 5, seed=3), lambda: cut_cylinder(10, 6, sweep=np.pi),
              lambda: cone(12, 4, r0=0.6), lambda: bumpy_disk(9, seed=2)]
    return [write_ply(folder / f"good{i}.ply", *makers[i]()) for i in range(n)]


def corrupt_mesh(path):
    """A PLY whose header promises what the body does not hold."""
    Path(path).write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 1000\nproperty float x\n"
                           b"end_header\n\x00\x01garbage")
    return Path(path)


def raising_mesh(path):
    """A mesh uvbake refuses with an InputError: NaN coordinates."""
    V, F = plane(6, 5)
    V[3] = np.nan
    return write_ply(path, V, F)


def slow_mesh(path, n=400):
    """A dense height field (2 (n-1)^2 triangles) whose unwrap takes many seconds."""
    st, F = grid(n, n, jitter=0.2, seed=1)
    x, y = st[:, 0], st[:, 1]
    V = np.column_stack([x, y, 0.3 * np.sin(6 * x) * np.cos(5 * y)])
    import trimesh

    Path(path).parent.mkdir(parents=True, exist_ok=True)
    trimesh.Trimesh(V, F, process=False).export(path)
    return Path(path)


def env():
    """Environment for subprocesses that must import this checkout's uvbake."""
    e = dict(os.environ)
    inherited = [e["PYTHONPATH"]] if e.get("PYTHONPATH") else []        # CI runs with none set
    e["PYTHONPATH"] = os.pathsep.join([str(REPO), str(REPO / "plugins"), *inherited])
    return e


class Cluster:
    """A ``dask scheduler`` and ``dask worker`` processes on 127.0.0.1 (random ports, no dashboards)."""

    def __init__(self, tmp):
        self.tmp = Path(tmp)
        self.tmp.mkdir(parents=True, exist_ok=True)
        self.procs = {}
        self.address = None

    def start(self, n_workers):
        sched_file = self.tmp / "scheduler.json"
        self._start("scheduler", [sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0",
                                  "--no-dashboard", "--scheduler-file", str(sched_file)])
        deadline = time.monotonic() + 60
        while not sched_file.exists():
            self._check_alive("scheduler", deadline)
            time.sleep(0.1)
        time.sleep(0.1)
        self.address = json.loads(sched_file.read_text())["address"]
        for i in range(n_workers):
            self.add_worker(f"w{i}")
        self.wait_for_workers(n_workers)

    def _start(self, name, argv):
        with open(self.tmp / f"{name}.log", "wb") as log:     # the process keeps its own copy of the handle
            self.procs[name] = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                                env=env(), start_new_session=True)

    def _check_alive(self, name, deadline):
        if self.procs[name].poll() is not None or time.monotonic() > deadline:
            raise RuntimeError(f"dask {name} did not start: {(self.tmp / f'{name}.log').read_text()[-2000:]}")

    def add_worker(self, name):
        self._start(name, [sys.executable, "-m", "dask", "worker", self.address, "--name", name, "--nthreads", "1",
                           "--nworkers", "1", "--host", "127.0.0.1", "--no-dashboard", "--death-timeout", "60"])

    def wait_for_workers(self, n):
        from distributed import Client

        with Client(self.address, timeout="30s") as c:
            c.wait_for_workers(n, timeout=60)

    def kill(self, name):
        """SIGKILL a worker's whole process group (nanny and worker process): a machine dying."""
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.procs[name].pid, signal.SIGKILL)
        self.procs[name].wait()

    def close(self):
        for name in reversed(list(self.procs)):
            p = self.procs[name]
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGTERM)
        for p in self.procs.values():
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGKILL)
                p.wait()


@contextlib.contextmanager
def cluster(tmp, n_workers=2):
    c = Cluster(tmp)
    try:
        c.start(n_workers)
        yield c
    finally:
        c.close()


def batch_cli(*args, timeout=120):
    """Run ``uvbake batch ARGS`` as a process; return (exit status, stdout, stderr)."""
    p = subprocess.run([sys.executable, "-m", "uvbake.cli", "batch", *map(str, args)], capture_output=True, text=True, check=False,
                       env=env(), timeout=timeout, stdin=subprocess.DEVNULL)
    return p.returncode, p.stdout, p.stderr


def summary(out):
    import pyarrow.parquet as pq

    return {r["asset"]: r for r in pq.read_table(Path(out) / "summary.parquet").to_pylist()}
