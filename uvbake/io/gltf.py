"""Binary glTF (GLB) writing and reading of textured meshes."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np

from uvbake.errors import InputError
from uvbake.io.corners import split_corners


def glb_bytes(V, F, corner_uv, png: bytes, *, vertex_colors=None, name="uvbake") -> bytes:
    """The GLB file of a textured mesh (see :func:`uvbake.io.export.save_textured`), as bytes.

    ``png`` is the texture, already encoded (the caller encodes it, so a failing encoder fails early).
    """
    source, uv, F_new = split_corners(F, corner_uv)
    pos = V[source].astype(np.float32)
    attrs = {"POSITION": pos, "NORMAL": _vertex_normals(V, F)[source],
             "TEXCOORD_0": np.column_stack([uv[:, 0], 1.0 - uv[:, 1]]).astype(np.float32)}
    if vertex_colors is not None:
        attrs["COLOR_0"] = vertex_colors[source].astype(np.float32)

    blob = bytearray()
    views, accessors = [], []

    def add_view(data: bytes, target=None):
        while len(blob) % 4:
            blob.append(0)
        view = {"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        blob.extend(data)
        views.append(view)
        return len(views) - 1

    prim_attrs = {}
    for key, arr in attrs.items():
        acc = {"bufferView": add_view(arr.tobytes(), _GL_ARRAY_BUFFER), "componentType": _GL_FLOAT,
               "count": len(arr), "type": f"VEC{arr.shape[1]}"}
        if key == "POSITION":
            acc["min"] = [float(x) for x in arr.min(axis=0)]
            acc["max"] = [float(x) for x in arr.max(axis=0)]
        accessors.append(acc)
        prim_attrs[key] = len(accessors) - 1
    idx = F_new.astype(np.uint32).reshape(-1)
    accessors.append({"bufferView": add_view(idx.tobytes(), _GL_ELEMENT_ARRAY_BUFFER),
                      "componentType": _GL_UNSIGNED_INT, "count": len(idx), "type": "SCALAR"})
    image_view = add_view(png)
    while len(blob) % 4:
        blob.append(0)

    gltf = {
        "asset": {"version": "2.0", "generator": "uvbake"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": name}],
        "meshes": [{"name": name, "primitives": [{"attributes": prim_attrs,
                                                  "indices": len(accessors) - 1,
                                                  "material": 0, "mode": 4}]}],
        "materials": [{"name": name, "doubleSided": True,
                       "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                "metallicFactor": 0.0, "roughnessFactor": 1.0}}],
        "textures": [{"sampler": 0, "source": 0}],
        "samplers": [{"magFilter": _GL_LINEAR, "minFilter": _GL_LINEAR_MIPMAP_LINEAR,
                      "wrapS": _GL_CLAMP_TO_EDGE, "wrapT": _GL_CLAMP_TO_EDGE}],
        "images": [{"bufferView": image_view, "mimeType": "image/png"}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    js = json.dumps(gltf, separators=(",", ":")).encode("utf-8")
    js += b" " * (-len(js) % 4)
    total = 12 + 8 + len(js) + 8 + len(blob)
    return b"".join([struct.pack("<4sII", b"glTF", 2, total),
                     struct.pack("<I4s", len(js), b"JSON"), js,
                     struct.pack("<I4s", len(blob), b"BIN\x00"), bytes(blob)])


_COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
              5126: np.float32}


_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def _load_glb(path):
    """V, F, corner_uv (v up) of the single primitive of a GLB written by uvbake."""
    data = Path(path).read_bytes()
    try:
        magic, version, total = struct.unpack_from("<4sII", data, 0)
        if magic != b"glTF" or version != 2:
            raise ValueError("not a glTF 2.0 binary")
        js_len, js_type = struct.unpack_from("<I4s", data, 12)
        gltf = json.loads(data[20:20 + js_len])
        bin_start = 20 + js_len + 8
        bin_len, _ = struct.unpack_from("<I4s", data, 20 + js_len)
        blob = data[bin_start:bin_start + bin_len]

        def accessor(i):
            acc = gltf["accessors"][i]
            view = gltf["bufferViews"][acc["bufferView"]]
            dtype = np.dtype(_COMPONENT[acc["componentType"]])
            width = _WIDTH[acc["type"]]
            start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
            stride = view.get("byteStride", dtype.itemsize * width)
            rows = [np.frombuffer(blob, dtype, width, start + r * stride) for r in range(acc["count"])] \
                if stride != dtype.itemsize * width else \
                [np.frombuffer(blob, dtype, acc["count"] * width, start)]
            return np.concatenate(rows).reshape(acc["count"], width)

        meshes = gltf.get("meshes", [])
        if len(meshes) != 1 or len(meshes[0]["primitives"]) != 1:
            raise ValueError("expected one mesh with one primitive")
        prim = meshes[0]["primitives"][0]
        V = accessor(prim["attributes"]["POSITION"]).astype(np.float64)
        F = accessor(prim["indices"]).reshape(-1, 3).astype(np.int64)
        uv = accessor(prim["attributes"]["TEXCOORD_0"]).astype(np.float64)
    except (ValueError, KeyError, IndexError, struct.error) as exc:
        raise InputError(f"{path}: cannot read as a uvbake GLB ({exc}); export it again") from None
    uv[:, 1] = 1.0 - uv[:, 1]
    return V, F, uv[F]


_GL_FLOAT, _GL_UNSIGNED_INT = 5126, 5125


_GL_ARRAY_BUFFER, _GL_ELEMENT_ARRAY_BUFFER = 34962, 34963


_GL_LINEAR, _GL_LINEAR_MIPMAP_LINEAR, _GL_CLAMP_TO_EDGE = 9729, 9987, 33071


def _vertex_normals(V, F):
    """Area-weighted unit vertex normals; (0,0,1) where undefined."""
    P = V[F]
    fn = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    vn = np.zeros_like(V)
    for k in range(3):
        np.add.at(vn, F[:, k], fn)
    norm = np.linalg.norm(vn, axis=1)
    ok = norm > 0
    vn[ok] /= norm[ok, None]
    vn[~ok] = (0.0, 0.0, 1.0)
    vn = vn.astype(np.float32)
    return vn / np.linalg.norm(vn, axis=1, keepdims=True)
