"""Renders issue 20's point light behind rough glass with Cycles and prints it against the
closed form that `tests/e2e/transmission.rs` checks wavetrace against (a developer tool, not
part of CI).

A rough glass plane (Principled BSDF, transmission 1, IOR 1.5, roughness 0.5, distribution
GGX: alpha 0.25) at z = 0, a point light of radius 0 and power P two units below it, and an
orthographic camera above looking straight down through the plane at the light: every pixel
sees the BTDF at normal incidence, where h = n and G = 1, so the radiance is
4 (1 - F0) D(n) E with D(n) = 1 / (pi alpha^2), F0 = 0.04 and E = (P / 4 pi) / 2^2 (Cycles'
point light of power P radiates P / 4 pi W/sr).

    /tmp/bpyenv/venv/bin/python tools/blender_rough_glass_point.py [--samples N] [--out DIR]
"""

import argparse
import math
import os
import tempfile

import bpy
from blender_common import empty_scene, render_mean, report, unbiased_cycles

ROUGHNESS = 0.5
IOR = 1.5
POWER = 100.0
DEPTH = 2.0


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--samples", type=int, default=1024)
    parser.add_argument("--out", default=tempfile.mkdtemp(prefix="rough-glass-"))
    args = parser.parse_args()

    scene = empty_scene(0.0)

    bpy.ops.mesh.primitive_plane_add(size=20.0, location=(0, 0, 0))
    plane = bpy.context.active_object
    mat = bpy.data.materials.new("rough glass")
    mat.use_nodes = True
    principled = mat.node_tree.nodes["Principled BSDF"]
    principled.distribution = "GGX"
    principled.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    principled.inputs["Transmission Weight"].default_value = 1.0
    principled.inputs["Roughness"].default_value = ROUGHNESS
    principled.inputs["IOR"].default_value = IOR
    plane.data.materials.append(mat)

    bpy.ops.object.light_add(type="POINT", location=(0, 0, -DEPTH))
    light = bpy.context.active_object
    light.data.energy = POWER
    light.data.shadow_soft_size = 0.0

    bpy.ops.object.camera_add(location=(0, 0, 1.5), rotation=(0, 0, 0))
    camera = bpy.context.active_object
    camera.data.type = "ORTHO"
    camera.data.ortho_scale = 0.002
    scene.camera = camera

    unbiased_cycles(scene, args.samples)
    n, mean = render_mean(scene, os.path.join(args.out, "cycles.exr"))
    alpha = ROUGHNESS**2
    f0 = ((IOR - 1) / (IOR + 1)) ** 2
    irradiance = POWER / (4 * math.pi) / DEPTH**2
    expected = 4 * (1 - f0) / (math.pi * alpha * alpha) * irradiance
    lines = [
        f"samples {args.samples}, {n} pixels",
        "Cycles      " + " ".join(f"{m:.4f}" for m in mean),
        f"closed form {expected:.4f}",
        "ratio       " + " ".join(f"{m / expected:.4f}" for m in mean),
    ]
    report(args.out, lines)


if __name__ == "__main__":
    main()
