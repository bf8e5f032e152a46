"""The file formats uvbake reads and writes, by extension (no numpy: the command line's parser and the
batch input scan use these without loading the readers)."""

#: File extensions load_mesh accepts (OBJ is parsed by uvbake, the rest by trimesh).
MESH_EXTENSIONS = (".ply", ".obj", ".off", ".glb", ".gltf", ".stl")

#: Extensions save_textured writes.
TEXTURED_EXTENSIONS = (".obj", ".glb")
