"""Named preview cameras and lighting modes: the vocabulary :mod:`uvbake.render` and the command line share.

No numpy here, so the ``uvbake`` parser (``uvbake --help``) offers these choices without loading the
numerical stack; :mod:`uvbake.render` turns the names into cameras.
"""

#: name -> (direction from the mesh centre to the eye, up vector); y-up camera frame (OpenGL/glTF).
VIEWS = {
    "front": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    "back": ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
    "angle": ((1.0, 1.0, 1.0), (0.0, 1.0, 0.0)),
}
DEFAULT_VIEWS = ("front", "back", "angle")
#: lighting modes: "unlit" shows the texture's own values; "lit" shades it with a sun light and an
#: ambient term (shape reads better; colours are no longer the texture's bytes)
LIGHTING = ("unlit", "lit")
TURNTABLE_ELEVATION_DEG = 20.0
