"""Reading and writing meshes: load (any source), PLY, OBJ, glTF, textured export, atomic writes.

Names and submodules import on first use, so ``from uvbake.io.atomic import ...`` or
``uvbake.io.formats`` does not load numpy (the command line's parser stays light).
"""

from uvbake._lazy import lazy_getattr

_NAMES = {
    "load_mesh": "uvbake.io.load:load_mesh",
    "MeshData": "uvbake.io.meshdata:MeshData",
    "LABEL_NAMES": "uvbake.io.load:LABEL_NAMES",
    "MESH_EXTENSIONS": "uvbake.io.formats:MESH_EXTENSIONS",
    "load_obj_uv": "uvbake.io.obj:load_obj_uv",
    "read_uv": "uvbake.io.uvread:read_uv",
    "save_obj": "uvbake.io.obj:save_obj",
    "read_ply_elements": "uvbake.io.ply:read_ply_elements",
    "atomic_write": "uvbake.io.atomic:atomic_write",
}
_SUBMODULES = ("atomic", "corners", "export", "formats", "gltf", "load", "meshdata", "obj", "ply", "uvread")
__getattr__ = lazy_getattr(__name__, {**_NAMES, **{m: f"{__name__}.{m}" for m in _SUBMODULES}})
__all__ = list(_NAMES)
