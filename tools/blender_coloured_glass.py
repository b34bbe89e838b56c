"""Renders issue 20's coloured-glass case with Cycles and prints it against the closed form
that `tests/e2e/volume.rs` checks wavetrace against (a developer tool, not part of CI).

A 2-unit glass cube (IOR 1.5, roughness 0) whose inside absorbs as glTF's
`KHR_materials_volume` says for attenuationColor [0.8, 0.5, 0.2] at attenuationDistance 1
(sigma_a = -ln(colour) / distance per channel), under a uniform white sky of radiance 1, seen
head-on through the middle of its top face by an orthographic camera. Cycles' Volume
Absorption node absorbs `density * (1 - colour)` per unit length, so the node gets
density = max(sigma_a) and colour = 1 - sigma_a / density (the same coefficients; Blender's
own glTF importer maps the extension differently). The closed form sums the reflections
between the two faces: f + (1 - f)^2 (f tau^2 + tau) / (1 - f^2 tau^2), tau = exp(-sigma_a 2),
f = 0.04.

    /tmp/bpyenv/venv/bin/python tools/blender_coloured_glass.py [--samples N] [--out DIR]
"""

import argparse
import math
import os
import tempfile

import bpy

COLOUR = (0.8, 0.5, 0.2)
DISTANCE = 1.0
SIDE = 2.0
IOR = 1.5


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--samples", type=int, default=256)
    parser.add_argument("--out", default=tempfile.mkdtemp(prefix="coloured-glass-"))
    args = parser.parse_args()
    sigma = [-math.log(c) / DISTANCE for c in COLOUR]
    density = max(sigma)
    node_colour = [1.0 - s / density for s in sigma]

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    background.inputs["Strength"].default_value = 1.0
    scene.world = world

    bpy.ops.mesh.primitive_cube_add(size=SIDE, location=(0, 0, 0))
    cube = bpy.context.active_object
    mat = bpy.data.materials.new("coloured glass")
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    principled = nodes["Principled BSDF"]
    principled.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    principled.inputs["Transmission Weight"].default_value = 1.0
    principled.inputs["Roughness"].default_value = 0.0
    principled.inputs["IOR"].default_value = IOR
    absorption = nodes.new("ShaderNodeVolumeAbsorption")
    absorption.inputs["Color"].default_value = (*node_colour, 1.0)
    absorption.inputs["Density"].default_value = density
    output = nodes["Material Output"]
    mat.node_tree.links.new(absorption.outputs["Volume"], output.inputs["Volume"])
    cube.data.materials.append(mat)

    bpy.ops.object.camera_add(location=(0, 0, 10), rotation=(0, 0, 0))
    camera = bpy.context.active_object
    camera.data.type = "ORTHO"
    camera.data.ortho_scale = 0.2
    scene.camera = camera

    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = args.samples
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    for bounces in ("max_bounces", "transmission_bounces", "glossy_bounces"):
        setattr(scene.cycles, bounces, 64)
    scene.cycles.transparent_max_bounces = 64
    scene.cycles.sample_clamp_direct = 0.0
    scene.cycles.sample_clamp_indirect = 0.0
    scene.cycles.filter_glossy = 0.0
    scene.cycles.caustics_reflective = True
    scene.cycles.caustics_refractive = True
    scene.view_settings.view_transform = "Standard"
    scene.render.resolution_x = 8
    scene.render.resolution_y = 8
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    path = os.path.join(args.out, "cycles.exr")
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)

    image = bpy.data.images.load(path)
    pixels = list(image.pixels)
    n = len(pixels) // 4
    mean = [sum(pixels[4 * i + c] for i in range(n)) / n for c in range(3)]
    f = ((IOR - 1) / (IOR + 1)) ** 2
    expected = []
    for s in sigma:
        tau = math.exp(-s * SIDE)
        expected.append(f + (1 - f) ** 2 * (f * tau * tau + tau) / (1 - f * f * tau * tau))
    lines = [
        f"samples {args.samples}, {n} pixels",
        "Cycles      " + " ".join(f"{m:.5f}" for m in mean),
        "closed form " + " ".join(f"{e:.5f}" for e in expected),
        "ratio       " + " ".join(f"{m / e:.4f}" for m, e in zip(mean, expected)),
    ]
    with open(os.path.join(args.out, "results.txt"), "w") as out:
        out.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
