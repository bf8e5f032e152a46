"""Small test meshes with known answers: developable patches admit an exact isometry to the plane."""

import numpy as np


def grid(nu, nv, *, jitter=0.0, seed=0):
    """A triangulated unit square: (s, t) in [0,1]^2 as (n,2), faces (m,3) counter-clockwise."""
    s, t = np.meshgrid(np.linspace(0, 1, nu), np.linspace(0, 1, nv), indexing="ij")
    st = np.stack([s.ravel(), t.ravel()], axis=1)
    if jitter:
        rng = np.random.default_rng(seed)
        inner = (st[:, 0] > 0) & (st[:, 0] < 1) & (st[:, 1] > 0) & (st[:, 1] < 1)
        st[inner] += rng.uniform(-jitter, jitter, size=(inner.sum(), 2)) / max(nu, nv)
    idx = np.arange(nu * nv).reshape(nu, nv)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return st, F.astype(np.int64)


def plane(nu=9, nv=7, *, jitter=0.3, seed=0):
    st, F = grid(nu, nv, jitter=jitter, seed=seed)
    V = np.column_stack([2.0 * st[:, 0], 1.5 * st[:, 1], np.zeros(len(st))])
    # tilt it so the plane is not z = 0
    c, s = np.cos(0.7), np.sin(0.7)
    return V @ np.array([[1, 0, 0], [0, c, s], [0, -s, c]]), F


def cut_cylinder(nu=16, nv=6, *, radius=1.0, height=1.5, sweep=1.6 * np.pi):
    """A cylinder opened along a line: developable, one boundary loop."""
    st, F = grid(nu, nv)
    th = sweep * st[:, 0]
    V = np.column_stack([radius * np.cos(th), radius * np.sin(th), height * st[:, 1]])
    return V, F


def cone(nu=16, nv=6, *, sweep=1.5 * np.pi, r0=0.4, r1=1.2, slope=0.8):
    """A frustum of a cone opened along a generator: developable, one boundary loop."""
    st, F = grid(nu, nv)
    th = sweep * st[:, 0]
    r = r0 + (r1 - r0) * st[:, 1]
    V = np.column_stack([r * np.cos(th), r * np.sin(th), slope * r])
    return V, F


def bumpy_disk(n=14, *, amp=0.35, seed=0):
    """A curved, non-developable disk (a height field over a jittered grid)."""
    st, F = grid(n, n, jitter=0.3, seed=seed)
    x, y = 2 * st[:, 0] - 1, 2 * st[:, 1] - 1
    V = np.column_stack([x, y, amp * np.sin(2.5 * x) * np.cos(2.0 * y) + 0.3 * (x * x - y * y)])
    return V, F


def torus(nu=12, nv=8, R=2.0, r=0.7):
    """A closed torus (genus 1), u around the axis, v around the tube."""
    idx = np.arange(nu * nv).reshape(nu, nv)
    a, b = idx, np.roll(idx, -1, 0)
    c, d = np.roll(b, -1, 1), np.roll(a, -1, 1)
    F = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, nu, endpoint=False),
                       np.linspace(0, 2 * np.pi, nv, endpoint=False), indexing="ij")
    V = np.stack([(R + r * np.cos(v)) * np.cos(u), (R + r * np.cos(v)) * np.sin(u), r * np.sin(v)], -1)
    return V.reshape(-1, 3), F


def open_tube(nu=24, nv=60, *, radius=0.2, length=4.0, bend=None):
    """An open tube (two boundary loops, genus 0), straight or bent along an arc of radius ``bend``:
    developable, but only once cut from one end to the other."""
    idx = np.arange(nu * nv).reshape(nv, nu)
    a, b = idx[:-1], np.roll(idx[:-1], -1, axis=1)
    c, d = np.roll(idx[1:], -1, axis=1), idx[1:]
    F = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    th, z = np.meshgrid(np.linspace(0, 2 * np.pi, nu, endpoint=False), np.linspace(0, length, nv))
    x, y = radius * np.cos(th), radius * np.sin(th)
    if bend is not None:
        x, z = (bend + x) * np.cos(z / bend) - bend, (bend + x) * np.sin(z / bend)
    return np.stack([x, y, z], -1).reshape(-1, 3), F.astype(np.int64)


def helical_strip(turns=1.5, n_theta=90, n_r=4, pitch=0.04):
    """A narrow ramp winding 1.5 times: its flattening wants to wind 540 degrees and overlap itself."""
    st, F = grid(n_theta, n_r)
    th = 2 * np.pi * turns * st[:, 0]
    r = 1.0 + 0.25 * st[:, 1]
    V = np.column_stack([r * np.cos(th), r * np.sin(th), pitch * th])
    return V, F
