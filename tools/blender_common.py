"""What the Blender tools share (developer tools run with Blender 4.5's Python module, `bpy`;
not part of CI): an empty scene under a uniform world, Cycles set up to be unbiased, and a
small render's mean written out and compared with a closed form."""

import os

import bpy


def empty_scene(radiance=0.0):
    """Blender's factory settings with no objects, under a uniform white world of `radiance`
    (0: black)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    background.inputs["Strength"].default_value = radiance
    scene.world = world
    return scene


def unbiased_cycles(scene, samples, bounces=64):
    """Cycles on the CPU at a fixed sample count, with nothing that trades bias for noise:
    no adaptive sampling, no denoising, no clamps, no glossy filter, caustics on."""
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    for kind in ("max_bounces", "transmission_bounces", "glossy_bounces",
                 "transparent_max_bounces"):
        setattr(scene.cycles, kind, bounces)
    scene.cycles.sample_clamp_direct = 0.0
    scene.cycles.sample_clamp_indirect = 0.0
    scene.cycles.filter_glossy = 0.0
    scene.cycles.caustics_reflective = True
    scene.cycles.caustics_refractive = True
    scene.view_settings.view_transform = "Standard"


def render_mean(scene, path, size=8):
    """Renders `size` x `size` pixels to the 32-bit EXR `path`; returns the pixel count and
    the mean of each of R, G, B."""
    scene.render.resolution_x = size
    scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    pixels = list(bpy.data.images.load(path).pixels)
    n = len(pixels) // 4
    return n, [sum(pixels[4 * i + c] for i in range(n)) / n for c in range(3)]


def report(out_dir, lines):
    """Prints `lines` and writes them to `out_dir`/results.txt."""
    with open(os.path.join(out_dir, "results.txt"), "w") as out:
        out.write("\n".join(lines) + "\n")
    print("\n".join(lines))
