"""Reading and writing meshes: load (any source), PLY, OBJ, glTF, textured export, atomic writes."""

from uvbake.io.atomic import atomic_write
from uvbake.io.load import LABEL_NAMES, MESH_EXTENSIONS, load_mesh
from uvbake.io.meshdata import MeshData
from uvbake.io.obj import load_obj_uv, save_obj
from uvbake.io.ply import read_ply_elements
from uvbake.io.uvread import read_uv

__all__ = [
    "load_mesh",
    "MeshData",
    "LABEL_NAMES",
    "MESH_EXTENSIONS",
    "load_obj_uv",
    "read_uv",
    "save_obj",
    "read_ply_elements",
    "atomic_write",
]
