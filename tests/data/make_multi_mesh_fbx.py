"""Make ``multi_mesh_blender.fbx``: a character as Blender exports one built of several meshes.

Run with a Python that has Blender as a module (``bpy``; see ``tests/blender_fbx_probe.py``)::

    python -c "from retarget_lib.io import save_glb; from retarget_lib.core.rig import Rig; \\
from retarget_lib.data.synthetic.characters import make_character; \\
save_glb(Rig.from_character(make_character('gus')), 'gus.glb')"
    BPY_PYTHON tests/data/make_multi_mesh_fbx.py -- gus.glb tests/data/multi_mesh_blender.fbx

The project's synthetic character ``gus`` (its glTF export) is imported by Blender's glTF importer,
decimated to a tenth (a small file; no UVs, no colours), and its head, hands and feet separated into
mesh objects of their own, each under its own object transform with the mesh data compensated (the
world positions do not change), as a character assembled from meshes authored apart is: a head in
centimetres, hands moved and turned, feet scaled unevenly. Blender's FBX exporter then writes every
mesh with its own skin (deformer and clusters, each with its mesh's bind matrix), and an eye
parented to the head bone without a skin. The project's own data: no licence beyond the
repository's.
"""

import sys

# isort: off
import bpy
import bmesh  # Blender's; importable once bpy is

# isort: on
from mathutils import Matrix

src, out = sys.argv[sys.argv.index("--") + 1 :]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=src)
arm = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
for o in [o for o in bpy.context.scene.objects if o.type == "MESH" and not o.vertex_groups]:
    bpy.data.objects.remove(o)  # the importer's bone display shape
body = next(o for o in bpy.context.scene.objects if o.type == "MESH")
bpy.context.view_layer.objects.active = body
decimate = body.modifiers.new("decimate", "DECIMATE")
decimate.ratio = 0.1
bpy.ops.object.modifier_apply(modifier=decimate.name)
while body.data.uv_layers:
    body.data.uv_layers.remove(body.data.uv_layers[0])
while body.data.color_attributes:
    body.data.color_attributes.remove(body.data.color_attributes[0])
names = [b.name for b in arm.data.bones]


def split(obj, keys, name):
    """Separate the faces whose vertices mostly follow bones named with one of ``keys``."""
    groups = {obj.vertex_groups[n].index for n in names if any(k in n for k in keys)}
    chosen = {
        v.index
        for v in obj.data.vertices
        if sum(g.weight for g in v.groups if g.group in groups) > 0.5
    }
    bpy.context.view_layer.objects.active = obj
    for o in bpy.context.scene.objects:
        o.select_set(o.name == obj.name)
    bpy.ops.object.mode_set(mode="EDIT")
    mesh = bmesh.from_edit_mesh(obj.data)
    for f in mesh.faces:
        f.select_set(all(v.index in chosen for v in f.verts))
    for v in mesh.verts:  # a vertex of no chosen face stays
        v.select_set(any(f.select for f in v.link_faces))
    bmesh.update_edit_mesh(obj.data)
    bpy.ops.mesh.separate(type="SELECTED")
    bpy.ops.object.mode_set(mode="OBJECT")
    new = next(o for o in bpy.context.selected_objects if o.name != obj.name)
    new.name = new.data.name = name
    return new


pieces = {
    split(body, ("Head", "Neck"), "HeadMesh"): Matrix.Diagonal((100, 100, 100, 1)),
    split(body, ("Hand",), "HandsMesh"): Matrix.Translation((0.3, -0.2, 0.5))
    @ Matrix.Rotation(0.7, 4, "Z"),
    split(body, ("Foot", "Toe"), "FeetMesh"): Matrix.Diagonal((0.5, 2.0, 1.0, 1)),
}
for obj, m in pieces.items():
    world = obj.matrix_world.copy()
    obj.data.transform(m.inverted())
    obj.matrix_world = world @ m
# an eye parented to the head bone, not skinned (as eyes, teeth and helmets often are): a small
# sphere on the front of the head
head_mesh = next(o for o in pieces if o.name == "HeadMesh")
front = max((head_mesh.matrix_world @ v.co for v in head_mesh.data.vertices), key=lambda c: -c.y)
bpy.ops.mesh.primitive_uv_sphere_add(segments=8, ring_count=6, radius=0.02)
eye = bpy.context.active_object
eye.name = eye.data.name = "Eye"
eye.parent, eye.parent_type, eye.parent_bone = arm, "BONE", "Head"
bpy.context.view_layer.update()
eye.matrix_world = Matrix.Translation(front)
bpy.ops.export_scene.fbx(filepath=out, add_leaf_bones=False, bake_anim=False)
print(
    "meshes",
    [(o.name, len(o.data.vertices)) for o in bpy.context.scene.objects if o.type == "MESH"],
)
