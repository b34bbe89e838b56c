"""Measures how bright Blender's glTF exports of point, spot and sun lights render in wavetrace
against Cycles rendering the same Blender scene (a developer tool, not part of CI).

For each light, a scene is built with Blender's Python module: a 20 x 20 plane (Principled
BSDF, base colour 0.8, roughness 1, specular 0: a Lambertian reflector), one light of known
power 2 units above it, and a camera looking straight down. Cycles renders it to EXR (CPU,
no adaptive sampling, no denoising, background black); Blender's own glTF exporter writes it
in each of its lighting modes (SPEC = "Standard", the default; COMPAT = "Unitless"; RAW);
wavetrace renders each export with each `--light-units`. The script prints the mean radiance
over a central square and over the whole image for every pair, the ratios wavetrace/Cycles,
and the closed forms of both means (albedo / pi * E at every pixel centre). The
results go to OUT/results.txt (Blender's own log goes to stdout).

    python3.11 -m venv /tmp/bpy && /tmp/bpy/bin/pip install 'bpy==4.5.*'
    cargo build --release
    /tmp/bpy/bin/python tools/blender_light_units.py --wavetrace target/release/wavetrace

Options: --out DIR (default: a temporary directory, kept), --samples N (Cycles and wavetrace
samples per pixel), --size N (image side). The spot is also rendered at several blends
(0, 0.15, 0.5, 1) to compare Blender's smoothstep cone with glTF's falloff: the ratio of the
whole-image means then measures the power in the cone.
"""

import argparse
import json
import math
import os
import struct
import subprocess
import sys
import tempfile

import bpy
from blender_common import empty_scene

ALBEDO = 0.8
HEIGHT = 2.0
POINT_WATTS = 1000.0
SUN_STRENGTH = 3.0
SPOT_SIZE_DEG = 60.0




def build(kind, size, blend=0.15):
    scene = empty_scene()
    # Before the export too: the exported camera's yfov follows the render's aspect ratio.
    scene.render.resolution_x = size
    scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    bpy.ops.mesh.primitive_plane_add(size=20.0, location=(0, 0, 0))
    plane = bpy.context.active_object
    mat = bpy.data.materials.new("white")
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (ALBEDO, ALBEDO, ALBEDO, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Metallic"].default_value = 0.0
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    plane.data.materials.append(mat)

    if kind == "point":
        light = bpy.data.lights.new("Light", "POINT")
        light.energy = POINT_WATTS
        light.shadow_soft_size = 0.0
    elif kind == "spot":
        light = bpy.data.lights.new("Light", "SPOT")
        light.energy = POINT_WATTS
        light.shadow_soft_size = 0.0
        light.spot_size = math.radians(SPOT_SIZE_DEG)
        light.spot_blend = blend
    else:
        light = bpy.data.lights.new("Light", "SUN")
        light.energy = SUN_STRENGTH
        light.angle = 0.0
    obj = bpy.data.objects.new("Light", light)
    obj.location = (0.0, 0.0, HEIGHT)  # lights point along their local -Z: straight down
    scene.collection.objects.link(obj)

    cam = bpy.data.cameras.new("Camera")
    cam.angle = math.radians(70.0)
    cam_obj = bpy.data.objects.new("Camera", cam)
    cam_obj.location = (0.0, 0.0, 6.0)
    scene.collection.objects.link(cam_obj)
    scene.camera = cam_obj
    return scene


def render_cycles(scene, path, size, samples):
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 4
    scene.cycles.seed = 1
    scene.cycles.light_sampling_threshold = 0.0  # no culling of dim light contributions
    scene.render.resolution_x = size
    scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.filter_size = 0.01  # box-like pixels, as wavetrace
    scene.view_settings.view_transform = "Standard"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


def export(path, mode):
    bpy.ops.export_scene.gltf(
        filepath=path,
        export_format="GLB",
        export_lights=True,
        export_cameras=True,
        export_import_convert_lighting_mode=mode,
    )


def glb_lights(path):
    with open(path, "rb") as f:
        data = f.read()
    length = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20 : 20 + length])
    return doc.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])


def exr_means(path, size):
    """(central-square mean, whole-image mean) of the red channel of an EXR (via Blender)."""
    img = bpy.data.images.load(path, check_existing=False)
    px = list(img.pixels)  # RGBA, rows bottom to top
    w, h = img.size
    reds = [px[4 * i] for i in range(w * h)]
    c0, c1 = int(w * 0.45), int(w * 0.55)
    central = [reds[y * w + x] for y in range(c0, c1) for x in range(c0, c1)]
    bpy.data.images.remove(img)
    return sum(central) / len(central), sum(reds) / len(reds)


def closed_form_means(kind, size, blend):
    """(central-square mean, whole-image mean) of albedo / pi * E over the pixel centres, E
    from the light's closed form (Blender's spot: smoothstep over Cycles' blend range)."""
    half = math.tan(math.radians(35.0))
    total, central, n_central = 0.0, 0.0, 0
    c0, c1 = int(size * 0.45), int(size * 0.55)
    for j in range(size):
        for i in range(size):
            u = ((i + 0.5) / size * 2 - 1) * half
            v = ((j + 0.5) / size * 2 - 1) * half
            x, y = 6.0 * u, 6.0 * v  # where the ray meets the plane z = 0
            if kind == "sun":
                e = SUN_STRENGTH
            else:
                r2 = x * x + y * y + HEIGHT**2
                cos = HEIGHT / math.sqrt(r2)
                e = POINT_WATTS / (4 * math.pi) * cos / r2
                if kind == "spot":
                    cos_half = math.cos(math.radians(SPOT_SIZE_DEG / 2))
                    if blend == 0:
                        e *= 1.0 if cos > cos_half else 0.0
                    else:
                        t = min(max((cos - cos_half) / ((1 - cos_half) * blend), 0.0), 1.0)
                        e *= t * t * (3 - 2 * t)
            radiance = ALBEDO / math.pi * e
            total += radiance
            if c0 <= i < c1 and c0 <= j < c1:
                central += radiance
                n_central += 1
    return central / n_central, total / size**2


def render_wavetrace(exe, glb, units, out, size, samples):
    subprocess.run(
        [exe, "render", glb, "-o", out, "--light-units", units, "--width", str(size),
         "--height", str(size), "--spp", str(samples), "--quiet"],
        check=True,
        capture_output=True,
    )


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--wavetrace", required=True)
    ap.add_argument("--out", default=None)
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--only", default=None, help="point, sun or spot")
    args = ap.parse_args(sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else None)
    out = args.out or tempfile.mkdtemp(prefix="light-units-")
    os.makedirs(out, exist_ok=True)
    exe = os.path.abspath(args.wavetrace)
    cases = [("point", None), ("sun", None), ("spot", 0.15), ("spot", 0.0), ("spot", 0.5),
             ("spot", 1.0)]
    readings = {"SPEC": "spec", "COMPAT": "unitless", "RAW": "raw"}
    results = open(os.path.join(out, "results.txt"), "w")

    def say(line):
        results.write(line + "\n")
        results.flush()

    say(f"results in {out}; {args.size}x{args.size}, {args.samples} samples")
    for kind, blend in cases:
        if args.only and kind != args.only:
            continue
        tag = kind if blend is None else f"spot-blend{blend}"
        scene = build(kind, args.size, blend if blend is not None else 0.15)
        cycles = os.path.join(out, f"{tag}-cycles.exr")
        render_cycles(scene, cycles, args.size, args.samples)
        cc, cw = exr_means(cycles, args.size)
        ec, ew = closed_form_means(kind, args.size, blend)
        say(f"\n{tag}: Cycles centre {cc:.6g} (closed form {ec:.6g}, x{cc / ec:.4f}), "
            f"whole image {cw:.6g} (closed form {ew:.6g}, x{cw / ew:.4f})")
        for mode, reading in readings.items():
            scene = build(kind, args.size, blend if blend is not None else 0.15)
            glb = os.path.join(out, f"{tag}-{mode}.glb")
            export(glb, mode)
            lights = glb_lights(glb)
            written = ", ".join(
                f"{l['type']} {l.get('intensity', 1.0):.6g}"
                + (f" cone {math.degrees(l['spot'].get('innerConeAngle', 0)):.3f}.."
                   f"{math.degrees(l['spot']['outerConeAngle']):.3f} deg" if "spot" in l else "")
                for l in lights)
            for units in ("spec", "unitless", "raw"):
                if mode != "SPEC" and units != reading:
                    continue
                wt = os.path.join(out, f"{tag}-{mode}-{units}.exr")
                try:
                    render_wavetrace(exe, glb, units, wt, args.size, args.samples)
                except subprocess.CalledProcessError as e:
                    say(f"  {mode:6} export ({written}) --light-units {units:8}: wavetrace "
                        f"failed: {e.stderr.decode().strip().splitlines()[-1]}")
                    continue
                wc, ww = exr_means(wt, args.size)
                say(f"  {mode:6} export ({written}) --light-units {units:8}: centre "
                    f"{wc:.6g} (x{wc / cc:.4f} Cycles), whole {ww:.6g} (x{ww / cw:.4f})")


if __name__ == "__main__":
    main()
