"""SIGINT and SIGTERM at any moment of a run: exit 130/143 within a second, nothing written, no
temporary file left (issue 15). The run is a real subprocess; a small driver marks the moment
(``READY`` on stdout) at which the test sends the signal, and the time to exit is measured."""

import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from meshgen import grid

DRIVER = textwrap.dedent('''
    import builtins, sys, time

    stage, argv = sys.argv[1], sys.argv[2:]

    def ready():
        sys.stdout.write("READY\\n")
        sys.stdout.flush()

    if stage == "imports":
        # a library that guards an optional import with `except BaseException` (trimesh does)
        # swallows the KeyboardInterrupt raised while it imports
        real_import = builtins.__import__

        def hooked(name, *args, **kwargs):
            if name == "trimesh" and "trimesh" not in sys.modules:
                ready()
                try:
                    time.sleep(5)
                except BaseException:
                    pass
            return real_import(name, *args, **kwargs)

        builtins.__import__ = hooked
    elif stage == "solve":
        import uvbake.flatten.solve as flatten
        solve = flatten.trust_region             # the default step's solver

        def marked(*args, **kwargs):
            ready()
            return solve(*args, **kwargs)

        flatten.trust_region = marked
    elif stage == "write":
        from uvbake.io import atomic
        write = atomic.OutputSet.write_bytes

        def slow(self, final, data):
            write(self, final, data)     # a temporary file now exists beside the output
            ready()
            time.sleep(5)

        atomic.OutputSet.write_bytes = slow
    from uvbake.cli import main
    sys.argv = ["uvbake", *argv]
    sys.exit(main())
''')


@pytest.fixture(scope="module")
def big_mesh(tmp_path_factory):
    """A plane big enough that solving it takes seconds (80 x 80 quads, 12,800 triangles)."""
    return _write_ply(tmp_path_factory.mktemp("big") / "big.ply", *grid(81, 81, jitter=0.2, seed=1))


def _write_ply(path, st, F):
    """A gently curved sheet over the (s, t) grid, as ASCII PLY (read through trimesh)."""
    V = np.column_stack([4 * st, 0.3 * np.sin(4 * st[:, 0]) * np.cos(4 * st[:, 1])])
    with open(path, "w") as f:
        f.write(f"ply\nformat ascii 1.0\nelement vertex {len(V)}\nproperty double x\nproperty double y\n"
                f"property double z\nelement face {len(F)}\nproperty list uchar int vertex_indices\nend_header\n")
        f.writelines(f"{x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in V)
        f.writelines(f"3 {a} {b} {c}\n" for a, b, c in F)
    return path


def _interrupt(tmp_path, stage, mesh, sig, extra=()):
    work = tmp_path / "work"
    work.mkdir()
    src = work / mesh.name
    src.write_bytes(mesh.read_bytes())
    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER)
    args = [sys.executable, str(driver), stage, str(src), "-q", "--json", str(work / "r.json"),
            "--bake", str(work / "checker.png"), "--texture-size", "256", "--init", "random", *extra]
    with subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) as proc:
        line = proc.stdout.readline()
        assert line.strip() == "READY", (line, proc.stderr.read())
        t0 = time.perf_counter()
        proc.send_signal(sig)
        try:
            proc.wait(timeout=30)
        finally:
            proc.kill()
        elapsed = time.perf_counter() - t0
        err = proc.stderr.read()
    left = sorted(p.name for p in work.iterdir())
    return proc.returncode, elapsed, err, left


@pytest.mark.parametrize("stage", ["imports", "solve", "write"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_stops_the_run_within_a_second_and_writes_nothing(stage, sig, big_mesh, tmp_path):
    code, elapsed, err, left = _interrupt(tmp_path, stage, big_mesh, sig)
    assert code == 128 + sig, err                 # 130 for SIGINT, 143 for SIGTERM
    assert elapsed < 1.0, f"{elapsed:.2f} s from the signal to the exit ({stage})"
    assert left == [big_mesh.name], left          # no output, no .part/.tmp file
    print(f"{stage} {sig!r}: exit {elapsed:.3f} s after the signal")
    assert "interrupted" in err and "Traceback" not in err
    assert err.strip().count("\n") == 0, err


def test_in_process_main_returns_the_status_and_restores_the_handlers(tmp_path, monkeypatch):
    # a library caller (or a test) gets 130 back, its own handlers back, and a cleared flag
    from uvbake import cancel
    from uvbake.cli import main

    mesh = _write_ply(tmp_path / "g.ply", *grid(4, 4))
    before = signal.getsignal(signal.SIGINT)

    def interrupted(*args, **kwargs):
        cancel.cancel(signal.SIGINT)
        cancel.check_cancelled()

    monkeypatch.setattr("uvbake.atlas.charting.make_charts", interrupted)
    assert main([str(mesh), "-q"]) == 130
    assert signal.getsignal(signal.SIGINT) is before
    assert not cancel.is_cancelled()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.ply"]
