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
from blender_common import empty_scene, render_mean, report, unbiased_cycles

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

    scene = empty_scene(1.0)

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

    unbiased_cycles(scene, args.samples)
    n, mean = render_mean(scene, os.path.join(args.out, "cycles.exr"))
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
    report(args.out, lines)


if __name__ == "__main__":
    main()
