"""Import a pinchmatch GLB with Blender's own glTF importer and print what Blender sees, as JSON.

    blender -b --factory-startup --python tools/blender_import_check.py -- scene.glb

Prints one line ``RESULT {...}``: per object its world matrix (Blender is Z-up, metres), its
dimensions and its ``pinchmatch:`` custom properties (glTF extras). tests/test_scenes.py runs it
when blender is there.
"""

import json
import sys

import numpy

if not hasattr(numpy, "bool"):
    # Debian's Blender 3.4 importer still says np.bool, gone from numpy >= 1.24
    numpy.bool = numpy.bool_

import bpy  # noqa: E402 - Blender's module, only inside Blender

path = sys.argv[sys.argv.index("--") + 1]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=path)
objects = {}
for ob in bpy.data.objects:
    extras = {}
    for key in ob.keys():
        if key.startswith("pinchmatch:"):
            value = ob[key]
            extras[key] = value if isinstance(value, (str, int, float, bool)) else list(value)
    objects[ob.name] = {"matrix_world": [list(row) for row in ob.matrix_world],
                        "dimensions": list(ob.dimensions), "extras": extras}
print("RESULT " + json.dumps(objects))
