"""One texel density across the assets of a batch (``uvbake batch --texel-density``, issue 13)."""

import json

import numpy as np
import pytest
from batchkit import good_meshes

from uvbake.errors import InputError


def _texel_area(obj_path, size):
    """Total area, in texels of a ``size``-texel square, of the UV triangles of a written OBJ."""
    lines = obj_path.read_text().splitlines()
    uv = np.array([[float(x) for x in ln.split()[1:3]] for ln in lines if ln.startswith("vt ")])
    tri = np.array([[int(p.split("/")[1]) - 1 for p in ln.split()[1:4]] for ln in lines if ln.startswith("f ")])
    T = uv[tri] * size
    return 0.5 * np.abs((T[:, 1, 0] - T[:, 0, 0]) * (T[:, 2, 1] - T[:, 0, 1])
                        - (T[:, 2, 0] - T[:, 0, 0]) * (T[:, 1, 1] - T[:, 0, 1])).sum()


def test_assets_of_a_batch_share_one_texel_density(tmp_path):
    from uvbake.batch import run

    srcs = good_meshes(tmp_path / "in", 2)
    table = run(srcs, tmp_path / "out", client="local", bake=None, preview_size_px=0, texel_density=48.0)
    assert table.column("status").to_pylist() == ["done", "done"]
    sizes, densities = [], []
    for src in srcs:
        d = tmp_path / "out" / "assets" / src.stem
        report = json.loads((d / "report.json").read_text())
        densities.append(report["atlas"]["texel_density"])
        sizes.append(report["atlas"]["texture_size_px"])
        # the written UVs are the packing reported: texel area = efficiency * texels of the atlas
        # (= density^2 * flattened area), to the OBJ's printed precision
        area = _texel_area(d / f"{src.stem}_uv.obj", sizes[-1])
        assert area == pytest.approx(report["atlas"]["efficiency"] * sizes[-1] ** 2, rel=1e-3)
    assert densities == pytest.approx([48.0, 48.0], rel=1e-9)


def test_batch_texel_density_is_checked_and_keys_the_cache(tmp_path):
    from uvbake.batch.run import normalise_options

    a = normalise_options(texel_density=48)
    assert a["unwrap"]["texel_density"] == 48.0 and a["unwrap"]["texture_size_px"] is None
    b = normalise_options(texel_density=48, texture_size_px=512)
    assert b["unwrap"]["texture_size_px"] == 512
    assert normalise_options()["unwrap"]["texture_size_px"] == 1024
    for bad in (0, -3, float("nan"), "x", True):
        with pytest.raises(InputError, match="texel_density="):
            normalise_options(texel_density=bad)


def test_batch_cli_passes_texel_density():
    from uvbake.cli.batch import _texture_options, parser

    args = parser().parse_args(["in", "-o", "out", "--texel-density", "256"])
    assert _texture_options(args) == {"texel_density": 256.0}
    args = parser().parse_args(["in", "-o", "out", "--texel-density", "256", "--texture-size", "2048"])
    assert _texture_options(args) == {"texel_density": 256.0, "texture_size_px": 2048}
    assert _texture_options(parser().parse_args(["in", "-o", "out"])) == {}
    assert _texture_options(parser().parse_args(["in", "-o", "out", "--texture-size", "2048x1024"])) == {
        "texture_size_px": (2048, 1024)}
