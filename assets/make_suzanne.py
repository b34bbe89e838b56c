"""Writes assets/suzanne.glb: Blender's monkey primitive, as a user brings a model.

Blender's "Add > Mesh > Monkey" (Suzanne), one level of Catmull-Clark subdivision applied,
smooth shaded, with one Principled BSDF material (an orange plastic), exported by Blender's
glTF exporter with its default options into an empty scene: no camera, no lights, so
`wavetrace render assets/suzanne.glb` is a bare model (it goes into the hexagonal room) and
`--env` renders it under an environment. Blender's front view looks along +Y at the monkey's
face, which the exporter turns to glTF +Z, the front wavetrace turns to its camera.

Needs Blender as a Python module (the README's pictures used 4.5.15 LTS):

    python3.11 -m venv /tmp/bpy && /tmp/bpy/bin/pip install 'bpy==4.5.*'
    /tmp/bpy/bin/python assets/make_suzanne.py
"""
import os

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.mesh.primitive_monkey_add(size=2.0)
monkey = bpy.context.active_object
monkey.name = "Suzanne"
subdivision = monkey.modifiers.new("Subdivision", "SUBSURF")
subdivision.levels = 1
bpy.ops.object.modifier_apply(modifier=subdivision.name)
bpy.ops.object.shade_smooth()

material = bpy.data.materials.new("OrangePlastic")
material.use_nodes = True
bsdf = material.node_tree.nodes["Principled BSDF"]
bsdf.inputs["Base Color"].default_value = (0.8, 0.25, 0.05, 1.0)
bsdf.inputs["Roughness"].default_value = 0.35
monkey.data.materials.append(material)

bpy.ops.export_scene.gltf(
    filepath=os.path.join(HERE, "suzanne.glb"), export_format="GLB"
)
