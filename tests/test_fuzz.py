"""Property-based fuzzing of the loaders and the public API (issue 15), with hypothesis.

Every outcome must be a result or a uvbake error (``UvbakeError``): never another exception, a
warning raised in our code (pytest's configuration makes those errors), a hang or a crash.
Examples are seeded (``derandomize=True``) and bounded, so CI runs the same cases each time in
well under a minute. A longer run is one command::

    python3 bench/fuzz.py --examples 5000          # or UVBAKE_FUZZ_EXAMPLES=5000 python3 -m pytest tests/test_fuzz.py
"""

import contextlib
import os
import signal

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, Phase, example, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import uvbake  # noqa: E402
from uvbake.errors import UvbakeError  # noqa: E402

#: Examples per test: a CI budget by default, more for a long run (see bench/fuzz.py).
SCALE = int(os.environ.get("UVBAKE_FUZZ_EXAMPLES") or 0)
HANG_S = 120           # one example taking longer than this is a hang


def _settings(ci_examples):
    return settings(max_examples=SCALE or ci_examples, derandomize=True, deadline=None, database=None,
                    suppress_health_check=list(HealthCheck), print_blob=True,
                    phases=(Phase.explicit, Phase.generate, Phase.shrink))


@contextlib.contextmanager
def _no_hang():
    """Fail an example that runs longer than HANG_S (SIGALRM; the main thread only)."""
    def alarm(signum, frame):
        raise AssertionError(f"hang: one example ran longer than {HANG_S} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(HANG_S)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def _outcome(call):
    """Run ``call``; a uvbake error is an outcome, anything else propagates (and fails)."""
    with _no_hang():
        try:
            out = call()
        except UvbakeError as exc:
            msg = str(exc)
            assert msg and "\n" not in msg, f"a uvbake error must be one line: {msg!r}"
            hypothesis.event(f"outcome: {type(exc).__name__}")
            return exc
    hypothesis.event("outcome: result")
    return out


# --------------------------------------------------------------------------------------------------
# loaders: random bytes (and damaged valid files) under every mesh extension

VALID = {
    ".obj": b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nf 1/1 2/2 3/3\nf 2/2 4/4 3/3\n",
    ".off": b"OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 1 3 2\n",
    ".ply": b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
            b"element face 2\nproperty list uchar int vertex_indices\nproperty int segment\nend_header\n"
            b"0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2 7\n3 1 3 2 7\n",
    ".stl": b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\n"
            b"endfacet\nendsolid t\n",
    ".gltf": b'{"asset": {"version": "2.0"}, "meshes": []}',
    ".glb": b"glTF\x02\x00\x00\x00\x14\x00\x00\x00",
}
TOKENS = [b"v", b"vt", b"f", b"OFF", b"ply", b"element", b"face", b"vertex", b"property", b"list", b"uchar",
          b"int", b"float", b"end_header", b"nan", b"inf", b"-1", b"0", b"1", b"3", b"1e308", b"\xef\xbb\xbf",
          b"binary_little_endian", b"format", b"ascii", b"1.0", b"/", b"\n", b" ", b"-0", b"99999999999"]


@st.composite
def mesh_bytes(draw):
    ext = draw(st.sampled_from(sorted(VALID)))
    kind = draw(st.sampled_from(["random", "tokens", "damaged", "damaged"]))
    if kind == "random":
        data = draw(st.binary(max_size=512))
    elif kind == "tokens":
        data = b" ".join(draw(st.lists(st.sampled_from(TOKENS), max_size=80)))
    else:
        data = bytearray(VALID[ext])
        for _ in range(draw(st.integers(0, 3))):
            op = draw(st.sampled_from(["flip", "cut", "insert", "delete"]))
            at = draw(st.integers(0, max(len(data) - 1, 0)))
            if op == "flip" and data:
                data[at] = draw(st.integers(0, 255))
            elif op == "cut":
                del data[at:]
            elif op == "insert":
                data[at:at] = draw(st.sampled_from(TOKENS))
            elif data:
                del data[at:at + draw(st.integers(1, 8))]
        data = bytes(data)
    return ext, data


@_settings(150)
@given(mesh_bytes())
# findings of the long run (bench/fuzz.py), kept as fixed cases: a 'vt' line with one coordinate
@example(case=(".obj", VALID[".obj"].replace(b"vt 0 1\n", b"vt 1\n")))
def test_loaders_return_a_mesh_or_a_uvbake_error(tmp_path_factory, case):
    ext, data = case
    path = tmp_path_factory.mktemp("fuzz") / f"m{ext}"
    path.write_bytes(data)
    out = _outcome(lambda: uvbake.load_mesh(path))
    if not isinstance(out, UvbakeError):
        assert out.V.ndim == 2 and out.V.shape[1] == 3 and out.F.ndim == 2 and out.F.shape[1] == 3
        assert len(out.F) == 0 or (out.F.min() >= 0 and out.F.max() < len(out.V))
    if ext == ".obj":
        from uvbake.cli.check import load_uv_mesh

        _outcome(lambda: load_uv_mesh(path))


# --------------------------------------------------------------------------------------------------
# the public API: random meshes with random defects, random option values

ODD = [None, "x", "1e-8", float("nan"), float("inf"), -1, 0, 1, 2.5, True, [1], -0.0, 10**30, np.int64(3)]


@st.composite
def defective_mesh(draw):
    nu, nv = draw(st.integers(2, 6)), draw(st.integers(2, 6))
    s, t = np.meshgrid(np.linspace(0, 1, nu), np.linspace(0, 1, nv), indexing="ij")
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    V = np.column_stack([s.ravel(), t.ravel(), draw(st.floats(0, 2)) * rng.random(nu * nv)])
    idx = np.arange(nu * nv).reshape(nu, nv)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    with np.errstate(all="ignore"):              # the defects themselves may overflow: that is the point
        return _defects(draw, V, F, rng)


def _defects(draw, V, F, rng):
    for defect in draw(st.lists(st.sampled_from(
            ["nan", "inf", "index", "negative", "repeat", "duplicate", "flip", "collapse", "scale", "piece",
             "noise", "float_faces", "empty", "shape", "pinch"]), max_size=3)):
        m, n = len(F), len(V)
        i = draw(st.integers(0, max(m - 1, 0)))
        if defect == "nan" and n:
            V[draw(st.integers(0, n - 1)), 0] = np.nan
        elif defect == "inf" and n:
            V[draw(st.integers(0, n - 1)), 1] = np.inf
        elif defect == "index" and m:
            F[i, 0] = n + draw(st.integers(0, 3))
        elif defect == "negative" and m:
            F[i, 1] = -1
        elif defect == "repeat" and m:
            F[i, 2] = F[i, 0]
        elif defect == "duplicate" and m:
            F = np.vstack([F, F[i]])
        elif defect == "flip" and m:
            F[i] = F[i, ::-1]
        elif defect == "collapse" and n:
            V[:] = V[0]
        elif defect == "scale":
            V = V * draw(st.sampled_from([1e300, 1e-300, 1e-30, 1e30, 0.0, -1.0]))
        elif defect == "piece" and n >= 3 and V.shape[1] == 3:
            V = np.vstack([V, V[:3] + 5.0])
            F = np.vstack([F, np.arange(n, n + 3)])
        elif defect == "noise":
            V = V + rng.normal(scale=0.3, size=V.shape)
        elif defect == "float_faces":
            F = F.astype(float) + draw(st.sampled_from([0.0, 0.5]))
        elif defect == "empty":
            F = F[:0]
        elif defect == "shape":
            V = V[:, :2]
        elif defect == "pinch" and m and F.ndim == 2 and F.shape[1] == 3 and n > 1:
            # two vertices made one: a non-manifold vertex (a pinch) when both were on the border
            j, k = draw(st.integers(0, n - 1)), draw(st.integers(0, n - 1))
            F = np.where(F == k, j, F)
    return V, F


options = st.fixed_dictionaries({}, optional={
    "alpha": st.one_of(st.floats(-0.5, 1.5), st.sampled_from(ODD)),
    "init": st.sampled_from(["lscm", "tutte", "random", "isomap", None, 1]),
    "backend": st.sampled_from(["lm", "lbfgs", "newton", None]),
    "tol": st.one_of(st.floats(1e-12, 1e-2), st.sampled_from(ODD)),
    "max_iter": st.one_of(st.integers(0, 30), st.sampled_from(ODD)),
    "seed": st.one_of(st.integers(-2, 2**33), st.sampled_from(ODD)),
})


@_settings(60)
@given(defective_mesh(), options)
# findings of the long run: an integer too large for a float as tol
@example(mesh=(np.array([[0., 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0]]), np.array([[0, 2, 3], [0, 3, 1]])),
         opts={"tol": 10**30})
@example(mesh=(np.array([[0., 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0]]), np.array([[0, 2, 3], [0, 3, 1]])),
         opts={"tol": 10**400, "alpha": 10**400})
# and a max_iter past nlopt's C int evaluation cap for the L-BFGS backend
@example(mesh=(np.array([[0., 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0]]), np.array([[0, 2, 3], [0, 3, 1]])),
         opts={"init": "random", "max_iter": 10**30, "backend": "lbfgs"})
def test_parameterize_returns_a_result_or_a_uvbake_error(mesh, opts):
    V, F = mesh
    opts.setdefault("max_iter", 30)
    out = _outcome(lambda: uvbake.parameterize(V, F, **opts))
    if not isinstance(out, UvbakeError):
        assert out.uv.shape == (len(V), 2) and np.all(np.isfinite(out.uv))
        assert np.isfinite(out.energy) and out.energy >= 0


@_settings(40)
@given(defective_mesh(), options, st.fixed_dictionaries({}, optional={
    "texture_size_px": st.sampled_from([16, 64, 15, 100000, "64", 64.0, None]),
    "gutter_px": st.sampled_from([0, 1, 4, -1, 3.5, 100]),
    "bake": st.sampled_from([None, "checker", "vertex-colors", "png"]),
    "auto_cut": st.booleans(), "repair": st.booleans(), "guarantee": st.booleans(),
    "workers": st.sampled_from([None, 1, 2, 0, "2"]),
}))
def test_unwrap_returns_a_result_or_a_uvbake_error(mesh, opts, atlas_opts):
    V, F = mesh
    opts.setdefault("max_iter", 30)
    atlas_opts.setdefault("texture_size_px", 64)
    atlas_opts.setdefault("gutter_px", 1)
    out = _outcome(lambda: uvbake.unwrap((V, F), **opts, **atlas_opts))
    if not isinstance(out, UvbakeError):
        assert out.corner_uv.shape == (len(out.F), 3, 2)
        assert np.all((out.corner_uv >= 0) & (out.corner_uv <= 1))
        assert isinstance(out.report["valid"], bool)


@_settings(100)
@given(st.integers(1, 40), st.sampled_from(["corner", "vertex", "bad_shape", "bad_faces"]),
       st.sampled_from([16, 64, 15, "64", 2.0, 128]), st.integers(0, 2**32 - 1),
       st.lists(st.sampled_from(["nan", "inf", "huge", "collapse", "int", "dup"]), max_size=2))
def test_validate_returns_a_report_or_a_uvbake_error(m, layout, res, seed, defects):
    rng = np.random.default_rng(seed)
    uv = rng.random((m, 3, 2)) if layout != "vertex" else rng.random((m + 2, 2))
    F = rng.integers(0, m + 2, size=(m, 3)) if layout == "vertex" else None
    if layout == "bad_shape":
        uv = uv.reshape(m, 6)
    if layout == "bad_faces":
        F = rng.integers(-1, 5, size=(m, 2))
    for d in defects:
        if d == "nan":
            uv = uv.astype(float)
            uv.flat[0] = np.nan
        elif d == "inf":
            uv = uv.astype(float)
            uv.flat[-1] = np.inf
        elif d == "huge":
            with np.errstate(over="ignore"):
                uv = uv * 1e200
        elif d == "collapse":
            uv = np.where(np.isfinite(uv), 0.5, uv)
        elif d == "int":
            with np.errstate(invalid="ignore"):
                uv = np.nan_to_num(uv * 3, posinf=7.0).astype(np.int64)
        elif d == "dup" and uv.ndim == 3:
            uv = np.concatenate([uv, uv])
    out = _outcome(lambda: uvbake.validate(uv, F, resolution_px=res))
    if not isinstance(out, UvbakeError):
        assert isinstance(out.valid, bool) and out.n_faces == len(out.chart_ids)
        assert not (out.valid and (out.n_flipped or out.n_overlaps))
