"""Binary glTF (GLB) writing of textured meshes (reading back: :func:`uvbake.io.uvread.read_uv`)."""

from __future__ import annotations

import json
import struct

import numpy as np

from uvbake.io.corners import split_corners


def glb_bytes(V: np.ndarray, F: np.ndarray, corner_uv: np.ndarray, png: bytes, *,
              vertex_colors: np.ndarray | None = None, name: str = "uvbake") -> bytes:
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

    def add_view(data: bytes, target: int | None = None) -> int:
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


_GL_FLOAT, _GL_UNSIGNED_INT = 5126, 5125


_GL_ARRAY_BUFFER, _GL_ELEMENT_ARRAY_BUFFER = 34962, 34963


_GL_LINEAR, _GL_LINEAR_MIPMAP_LINEAR, _GL_CLAMP_TO_EDGE = 9729, 9987, 33071


def _vertex_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
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
