"""A pre-imported parent that forks one child process per asset: ``python -m uvbake.batch.zygote``.

Starting ``python -m uvbake.batch.child`` for every asset costs an interpreter start and the imports
(numpy, scipy, trimesh, CHOLMOD, Open3D): about 1 s per asset on this 2-core machine, as much as
unwrapping a small asset. The zygote pays that once per worker thread and then ``fork()``s a child per
asset, which still gives every asset its own process (killable at its time limit, a crash stays in
it). The zygote is single-threaded when it forks (it sets one BLAS/OpenMP thread before importing;
checked in tests/test_batch_inputs.py), which is what makes ``fork`` after these imports safe.

Protocol (lines on the zygote's stdin / stdout): the worker writes a spec path; the zygote forks,
answers ``pid <pid>``, waits for the child and answers ``exit <waitstatus>``. The child starts its own
session, so ``killpg(pid)`` stops it and anything it started. The zygote exits at end of input (its
worker is gone); the child exits on its own when the worker process disappears (``watch_pid``).
"""

from __future__ import annotations

import os
import sys

PRELOAD = ("uvbake.atlas.pipeline", "uvbake.io.export", "uvbake.batch.child", "uvbake.render", "uvbake.atlas.bake",
           "open3d",
           "trimesh", "PIL.Image")


def main() -> None:
    import importlib

    for name in PRELOAD:
        importlib.import_module(name)
    from uvbake.batch.child import main as child_main
    from uvbake.flatten.solvers.linalg import cholmod_available

    cholmod_available()           # load CHOLMOD and its BLAS once, before any fork
    out = sys.stdout
    for line in sys.stdin:
        spec = line.strip()
        if not spec:
            continue
        log = os.path.join(os.path.dirname(spec), "child.log")
        pid = os.fork()
        if pid == 0:              # the child: own session, output to the staging log, then the asset
            try:
                os.setsid()
                fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
                os.dup2(fd, 1)
                os.dup2(fd, 2)
                os.close(fd)
                devnull = os.open(os.devnull, os.O_RDONLY)
                os.dup2(devnull, 0)
                child_main([spec])            # never returns: os._exit
            finally:
                os._exit(71)
        out.write(f"pid {pid}\n")
        out.flush()
        _, status = os.waitpid(pid, 0)
        out.write(f"exit {status}\n")
        out.flush()


if __name__ == "__main__":
    main()
