"""Import an FBX with Blender's own importer and print what Blender made of it as JSON.

Run by ``tests/test_fbx.py`` with the Python of a virtual environment that has Blender as a module
(``python3.11 -m venv /work/bpy-venv && /work/bpy-venv/bin/pip install bpy``); not part of the
library (``bpy`` pins ``numpy<2``). Usage: ``PYTHON probe.py FILE.fbx`` -> JSON on stdout's last
line: bones (names, parents), the mesh's vertex count and vertex groups (name -> {vertex: weight}),
the scene's frame rate, the action's frame range, and every bone's head in world space at every
frame of that range and the skinned mesh's vertices at the last frame, converted back to +Y up
(Blender is +Z up: ``(x, y, z)_blender = (x, -z, y)``).
"""

import json
import sys

import bpy

bpy.ops.wm.read_factory_settings(use_empty=True)
result = bpy.ops.import_scene.fbx(filepath=sys.argv[1])
armatures = [o for o in bpy.context.scene.objects if o.type == "ARMATURE"]
meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
arm, mesh = armatures[0], meshes[0]
scene = bpy.context.scene
action = arm.animation_data.action if arm.animation_data else None
start, end = (int(round(v)) for v in action.frame_range) if action else (scene.frame_current,) * 2
names = [b.name for b in arm.data.bones]
groups = {g.index: g.name for g in mesh.vertex_groups}
weights = {name: {} for name in groups.values()}
for v in mesh.data.vertices:
    for g in v.groups:
        weights[groups[g.group]][v.index] = g.weight
heads = []
for frame in range(start, end + 1):
    scene.frame_set(frame)
    heads.append([list(arm.matrix_world @ arm.pose.bones[n].head) for n in names])
heads = [[[x, z, -y] for x, y, z in frame] for frame in heads]
# the skinned mesh as Blender deforms it at the last frame (world space, +Y up)
scene.frame_set(end)
evaluated = mesh.evaluated_get(bpy.context.evaluated_depsgraph_get())
deformed = [
    [w.x, w.z, -w.y] for w in (evaluated.matrix_world @ v.co for v in evaluated.data.vertices)
]
out = {
    "import": sorted(result),
    "armatures": len(armatures),
    "meshes": len(meshes),
    "bones": names,
    "parents": [b.parent.name if b.parent else None for b in arm.data.bones],
    "vertices": len(mesh.data.vertices),
    "mesh_vertices": [
        [w.x, w.z, -w.y] for w in (mesh.matrix_world @ v.co for v in mesh.data.vertices)
    ],
    "weights": weights,
    "fps": scene.render.fps / scene.render.fps_base,
    "frame_range": [start, end],
    "action": action.name if action else None,
    "heads": heads,
    "deformed_last_frame": deformed,
}
print(json.dumps(out))
