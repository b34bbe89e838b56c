"""Renders small Blender scenes whose materials read textures with Cycles and, through
Blender's glTF export, with wavetrace, and compares them (a developer tool, not part of CI).

Cases (`--only NAME`):
- `orm`: a cube whose one Non-Color image is its occlusion (R, through the "glTF Material
  Output" group), roughness (G) and metallic (B) map, in 2 x 2 patches per face;
- `normal`: a plane under a sun with a tangent-space normal map of bumps (strength 1 and 2;
  0: the map is not connected, the baseline);
- `p_`: a smooth sphere of one Principled material on a grey floor: rough metal, plastic,
  rough transmission, specular tint (with and without transmission), and a clear coat over a
  normal-mapped base with its own coat normal map;
- `p_film`: the sphere under a thin film (Principled "Thin Film Thickness" and "Thin Film
  IOR"), over a dark and over a light dielectric. Blender 4.5's glTF exporter and importer
  drop the film, so the exported file gets its `KHR_materials_iridescence` added here
  (factor 1, the same thickness and index) and Cycles renders the .blend: what Blender's
  import would give if it read the extension.

Each case prints the whole-image mean of wavetrace and Cycles, their ratio, and the median
over 8 x 8-pixel blocks of |wavetrace - Cycles| / Cycles. Results go to OUT/results.txt.

    python3.11 -m venv /tmp/bpy && /tmp/bpy/bin/pip install 'bpy==4.5.*'
    cargo build --release
    /tmp/bpy/bin/python tools/blender_textures.py --wavetrace target/release/wavetrace
"""

import argparse
import math
import os
import subprocess
import sys
import tempfile

import bpy
from blender_common import empty_scene


def image(name, size, texel, path, colourspace="Non-Color"):
    """A `size` x `size` PNG image from `texel(x, y) -> (r, g, b)` (y up), saved to `path`."""
    img = bpy.data.images.new(name, size, size, alpha=False)
    px = []
    for y in range(size):
        for x in range(size):
            px.extend(texel(x, y))
            px.append(1.0)
    img.pixels = px
    img.filepath_raw = path
    img.file_format = "PNG"
    img.save()
    img.colorspace_settings.name = colourspace
    return img


def material_output_group():
    """The node group Blender's glTF exporter reads occlusion from."""
    group = bpy.data.node_groups.new("glTF Material Output", "ShaderNodeTree")
    group.interface.new_socket("Occlusion", in_out="INPUT", socket_type="NodeSocketFloat")
    group.nodes.new("NodeGroupInput")
    return group


def camera(scene, location, target, lens_angle=40.0):
    cam = bpy.data.cameras.new("Camera")
    cam.angle = math.radians(lens_angle)
    obj = bpy.data.objects.new("Camera", cam)
    obj.location = location
    direction = [t - l for t, l in zip(target, location)]
    from mathutils import Vector

    obj.rotation_euler = Vector(direction).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(obj)
    scene.camera = obj


def sun(scene, strength, rotation):
    light = bpy.data.lights.new("Sun", "SUN")
    light.energy = strength
    light.angle = 0.0
    obj = bpy.data.objects.new("Sun", light)
    obj.rotation_euler = rotation
    scene.collection.objects.link(obj)


def build_orm(out, size, colourspace="Non-Color"):
    scene = empty_scene(radiance=0.0)
    scene.render.resolution_x = scene.render.resolution_y = size
    bpy.ops.mesh.primitive_cube_add(size=2.0)
    cube = bpy.context.active_object
    cube.rotation_euler = (0.0, 0.0, math.radians(30.0))

    def orm(x, y):
        # 16 x 16: 4 x 4 patches; occlusion varies slowly, roughness and metal in a checker.
        px, py = x // 4, y // 4
        return (0.3 + 0.7 * px / 3.0, 0.15 if (px + py) % 2 else 0.7, 1.0 if py % 2 else 0.0)

    img = image("orm", 16, orm, os.path.join(out, f"orm-{colourspace}.png"), colourspace)
    mat = bpy.data.materials.new("orm")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.8, 0.45, 0.2, 1.0)
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.interpolation = "Closest"
    sep = nodes.new("ShaderNodeSeparateColor")
    links.new(tex.outputs["Color"], sep.inputs["Color"])
    links.new(sep.outputs["Green"], bsdf.inputs["Roughness"])
    links.new(sep.outputs["Blue"], bsdf.inputs["Metallic"])
    group = nodes.new("ShaderNodeGroup")
    group.node_tree = material_output_group()
    links.new(sep.outputs["Red"], group.inputs["Occlusion"])
    cube.data.materials.append(mat)
    sun(scene, 3.0, (math.radians(40.0), 0.0, math.radians(60.0)))
    camera(scene, (5.0, -5.0, 4.0), (0.0, 0.0, 0.0))
    return scene


def build_normal(out, size, strength):
    scene = empty_scene(radiance=0.0)
    scene.render.resolution_x = scene.render.resolution_y = size
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    plane = bpy.context.active_object

    def bumps(x, y):
        # Tilts of 30 degrees in four directions, in 2 x 2 patches of an 8 x 8 image.
        s, c = math.sin(math.radians(30)), math.cos(math.radians(30))
        k = (x // 4) + 2 * (y // 4)
        n = [(s, 0, c), (-s, 0, c), (0, s, c), (0, -s, c)][k]
        return tuple(0.5 * v + 0.5 for v in n)

    img = image(f"normal{strength}", 8, bumps, os.path.join(out, f"normal{strength}.png"))
    mat = bpy.data.materials.new("bumpy")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.interpolation = "Closest"
    nmap = nodes.new("ShaderNodeNormalMap")
    nmap.inputs["Strength"].default_value = strength
    links.new(tex.outputs["Color"], nmap.inputs["Color"])
    if strength > 0.0:
        links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    plane.data.materials.append(mat)
    sun(scene, 3.0, (math.radians(60.0), 0.0, math.radians(20.0)))
    camera(scene, (0.0, 0.0, 6.0), (0.0, 0.0, 0.0))
    return scene


def build_principled(out, size, settings, normal_strength=0.0, coat_normal=False):
    """A smooth UV sphere of one Principled material (`settings`: input name -> value) on a
    grey floor, under a sun (no sky: glTF carries none); optionally the `normal` case's map on the base
    (at `normal_strength`) and, at strength 1, on the coat."""
    scene = empty_scene(radiance=0.0)
    scene.render.resolution_x = scene.render.resolution_y = size
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=48, ring_count=24)
    sphere = bpy.context.active_object
    bpy.ops.object.shade_smooth()
    sphere.location = (0.0, 0.0, 1.0)
    bpy.ops.mesh.primitive_plane_add(size=8.0)
    floor = bpy.context.active_object
    grey = bpy.data.materials.new("floor")
    grey.use_nodes = True
    grey.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.4, 0.4, 0.4, 1)
    grey.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = 1.0
    floor.data.materials.append(grey)
    mat = bpy.data.materials.new("principled")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes["Principled BSDF"]
    for name, value in settings.items():
        bsdf.inputs[name].default_value = value
    if normal_strength > 0.0:

        def bumps(x, y):
            s, c = math.sin(math.radians(30)), math.cos(math.radians(30))
            k = (x // 4) + 2 * (y // 4)
            n = [(s, 0, c), (-s, 0, c), (0, s, c), (0, -s, c)][k]
            return tuple(0.5 * v + 0.5 for v in n)

        img = image("pbumps", 8, bumps, os.path.join(out, "pbumps.png"))
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = img
        tex.interpolation = "Closest"
        nmap = nodes.new("ShaderNodeNormalMap")
        nmap.inputs["Strength"].default_value = normal_strength
        links.new(tex.outputs["Color"], nmap.inputs["Color"])
        links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
        if coat_normal:
            cmap = nodes.new("ShaderNodeNormalMap")
            links.new(tex.outputs["Color"], cmap.inputs["Color"])
            links.new(cmap.outputs["Normal"], bsdf.inputs["Coat Normal"])
    sphere.data.materials.append(mat)
    sun(scene, 3.0, (math.radians(40.0), 0.0, math.radians(30.0)))
    camera(scene, (0.0, -6.0, 3.0), (0.0, 0.0, 0.8))
    return scene


def render_cycles(scene, path, samples, filter_size=0.01):
    """Unbiased Cycles (no adaptive sampling, denoising or clamps); `filter_size` 0.01 is a
    point filter, 1.5 Cycles' default Blackman-Harris (wavetrace's default for model files)."""
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 8
    scene.cycles.seed = 1
    scene.cycles.light_sampling_threshold = 0.0
    scene.cycles.sample_clamp_direct = 0.0
    scene.cycles.sample_clamp_indirect = 0.0
    scene.cycles.filter_glossy = 0.0
    scene.render.resolution_percentage = 100
    scene.render.filter_size = filter_size
    scene.view_settings.view_transform = "Standard"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


def export(path):
    bpy.ops.export_scene.gltf(
        filepath=path, export_format="GLB", export_lights=True, export_cameras=True
    )


def add_iridescence(glb, material, film):
    """Adds `KHR_materials_iridescence` (`film`, its JSON) to the material named `material`
    of the GLB file `glb`, in place."""
    import json
    import struct

    data = open(glb, "rb").read()
    magic, version, _ = struct.unpack_from("<III", data, 0)
    json_length, json_type = struct.unpack_from("<II", data, 12)
    doc = json.loads(data[20 : 20 + json_length])
    rest = data[20 + json_length :]
    for m in doc["materials"]:
        if m.get("name") == material:
            m.setdefault("extensions", {})["KHR_materials_iridescence"] = film
    doc.setdefault("extensionsUsed", []).append("KHR_materials_iridescence")
    text = json.dumps(doc).encode()
    text += b" " * ((4 - len(text) % 4) % 4)
    header = struct.pack("<III", magic, version, 20 + len(text) + len(rest))
    with open(glb, "wb") as out:
        out.write(header + struct.pack("<II", len(text), json_type) + text + rest)


def exr_channel_means(path):
    img = bpy.data.images.load(path, check_existing=False)
    px = list(img.pixels)
    n = len(px) // 4
    bpy.data.images.remove(img)
    return [sum(px[4 * i + c] for i in range(n)) / n for c in range(3)]


def exr_luma(path):
    img = bpy.data.images.load(path, check_existing=False)
    px = list(img.pixels)
    w, h = img.size
    bpy.data.images.remove(img)
    return w, h, [(px[4 * i] + px[4 * i + 1] + px[4 * i + 2]) / 3 for i in range(w * h)]


def compare(ours, cycles, block=8):
    w, h, a = ours
    _, _, b = cycles
    errors = []
    for by in range(0, h, block):
        for bx in range(0, w, block):
            idx = [y * w + x for y in range(by, by + block) for x in range(bx, bx + block)]
            sa, sb = sum(a[i] for i in idx), sum(b[i] for i in idx)
            if sb > 1e-3 * block * block:
                errors.append(abs(sa - sb) / sb)
    errors.sort()
    median = errors[len(errors) // 2] if errors else float("nan")
    ma, mb = sum(a) / len(a), sum(b) / len(b)
    return ma, mb, median


def centre_ratio(ours, cycles, fraction=20 / 64):
    """wavetrace / Cycles over the central square (`fraction` of the width: the sphere's
    middle in the `p_` scenes)."""
    w, h, a = ours
    _, _, b = cycles
    half = max(1, int(w * fraction / 2))
    idx = [y * w + x for y in range(h // 2 - half, h // 2 + half)
           for x in range(w // 2 - half, w // 2 + half)]
    return sum(a[i] for i in idx) / sum(b[i] for i in idx)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--wavetrace", required=True)
    ap.add_argument("--out", default=None)
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--only", default=None)
    ap.add_argument("--extra", default="", help="more wavetrace arguments, space separated")
    ap.add_argument("--cycles-only", action="store_true",
                    help="render (and keep) the Cycles references only")
    args = ap.parse_args(sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else None)
    out = args.out or tempfile.mkdtemp(prefix="blender-textures-")
    os.makedirs(out, exist_ok=True)
    exe = os.path.abspath(args.wavetrace)
    cases = {
        "orm": lambda: build_orm(out, args.size),
        # The same image left at Blender's default sRGB: Cycles decodes it before the
        # Separate Color node; the exporter writes the file's bytes as they are.
        "orm_srgb": lambda: build_orm(out, args.size, "sRGB"),
        # The same plane without its normal map: the baseline the mapped ones compare with.
        "normal0": lambda: build_normal(out, args.size, 0.0),
        "normal1": lambda: build_normal(out, args.size, 1.0),
        "normal2": lambda: build_normal(out, args.size, 2.0),
        # Principled spheres (issue 34's remaining gaps).
        "p_metal": lambda: build_principled(
            out, args.size, {"Base Color": (0.9, 0.6, 0.3, 1), "Metallic": 1.0, "Roughness": 0.7}
        ),
        "p_plastic": lambda: build_principled(
            out, args.size, {"Base Color": (0.8, 0.8, 0.8, 1), "Roughness": 0.3}
        ),
        "p_rough_glass": lambda: build_principled(
            out, args.size,
            {"Base Color": (0.8, 0.8, 0.8, 1), "Transmission Weight": 0.2, "IOR": 1.45,
             "Roughness": 0.4},
        ),
        "p_specular": lambda: build_principled(
            out, args.size,
            {"Base Color": (0.3, 0.5, 0.2, 1), "Roughness": 0.3, "Specular IOR Level": 1.0,
             "Specular Tint": (1.0, 0.6, 0.3, 1)},
        ),
        "p_specular_glass": lambda: build_principled(
            out, args.size,
            {"Base Color": (0.3, 0.5, 0.2, 1), "Roughness": 0.3, "Specular IOR Level": 1.0,
             "Specular Tint": (1.0, 0.6, 0.3, 1), "Transmission Weight": 0.3},
        ),
        "p_coat": lambda: build_principled(
            out, args.size,
            {"Base Color": (0.02, 0.05, 0.3, 1), "Roughness": 0.5, "Coat Weight": 0.225,
             "Coat Roughness": 0.1},
            normal_strength=2.0, coat_normal=True,
        ),
        # The same without the coat's own normal map (the coat over the smooth normal).
        "p_coat_smooth": lambda: build_principled(
            out, args.size,
            {"Base Color": (0.02, 0.05, 0.3, 1), "Roughness": 0.5, "Coat Weight": 0.225,
             "Coat Roughness": 0.1},
            normal_strength=2.0, coat_normal=False,
        ),
        # Thin films (iridescence): Cycles' model, set by hand in the .blend, added to the
        # exported file by add_iridescence.
        "p_film_dark": lambda: build_principled(
            out, args.size,
            {"Base Color": (0.05, 0.05, 0.05, 1), "Roughness": 0.3, "Thin Film Thickness": 300.0,
             "Thin Film IOR": 2.0},
        ),
        "p_film_light": lambda: build_principled(
            out, args.size,
            {"Base Color": (0.8, 0.8, 0.8, 1), "Roughness": 0.5, "Thin Film Thickness": 450.0,
             "Thin Film IOR": 1.6},
        ),
    }
    films = {
        "p_film_dark": {"iridescenceFactor": 1.0, "iridescenceIor": 2.0,
                        "iridescenceThicknessMaximum": 300.0},
        "p_film_light": {"iridescenceFactor": 1.0, "iridescenceIor": 1.6,
                         "iridescenceThicknessMaximum": 450.0},
    }
    lines = []
    for name, build in cases.items():
        if args.only and not name.startswith(args.only):
            continue
        scene = build()
        glb = os.path.join(out, f"{name}.glb")
        export(glb)
        if name in films:
            add_iridescence(glb, "principled", films[name])
        cyc = os.path.join(out, f"{name}-cycles.exr")
        if not os.path.exists(cyc):
            render_cycles(scene, cyc, args.samples)
        if args.cycles_only:
            continue
        ours = os.path.join(out, f"{name}-wavetrace.exr")
        subprocess.run(
            [exe, "render", glb, "-o", ours, "--width", str(args.size), "--height",
             str(args.size), "--spp", str(args.samples), "--quiet"] + args.extra.split(),
            check=True,
        )
        ma, mb, median = compare(exr_luma(ours), exr_luma(cyc))
        channels = [a / b for a, b in zip(exr_channel_means(ours), exr_channel_means(cyc))]
        centre = centre_ratio(exr_luma(ours), exr_luma(cyc))
        lines.append(f"{name}: wavetrace {ma:.5f} cycles {mb:.5f} ratio {ma / mb:.4f} "
                     f"(R G B {channels[0]:.4f} {channels[1]:.4f} {channels[2]:.4f}) "
                     f"median block error {median:.4f}, sphere centre ratio {centre:.4f}")
        print(lines[-1], flush=True)
    with open(os.path.join(out, "results.txt"), "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
