"""Equal-time error of wavetrace against Blender's Cycles on the seed room (issue 22; a
developer tool, not part of CI). Run it with Blender's Python module:

    python3.11 -m venv /tmp/bpyenv/venv && /tmp/bpyenv/venv/bin/pip install 'bpy==4.5.*'
    cargo build --release --features examples --example equal_time --example image_error
    PY=/tmp/bpyenv/venv/bin/python
    $PY tools/cycles_room.py build OUT            # OUT/room.blend and its export OUT/room.glb
    $PY tools/cycles_room.py render OUT/room.blend OUT/ref-cycles.exr --spp 512 --seed 7
    target/release/wavetrace render OUT/room.glb -o OUT/ref-wt.exr --width 256 --height 256 \
        --spp 2048 --seed 7
    $PY tools/cycles_room.py compare OUT/ref-wt.exr OUT/ref-cycles.exr   # the references' means
    $PY tools/cycles_room.py table OUT --wt-ref OUT/ref-wt.exr --cycles-ref OUT/ref-cycles.exr \
        [--budgets 8 32] [--repeats 3]

`build` makes the room of `scenes/room.toml` in Blender (hexagonal floor and ceiling, six
walls, the tetrahedron as meshes; the spheres as smooth UV spheres of 128 x 64 faces) with
materials that map exactly onto wavetrace's (docs/importing.md): Lambertian walls are
Principled BSDFs with metallic 0 and Specular IOR Level 0, the mirror is metallic 1 roughness
0 with a white base, the glass transmission 1 roughness 0 IOR 1.5, the light a black
Principled BSDF emitting radiance 20 (Blender's Emission Strength is radiance) from its front
only (backface culling on, which the exporter writes as `doubleSided: false`). Blender's own
glTF exporter writes the .glb. Cycles emits from both sides of a mesh, so in the .blend the
light's material then gets the emission only where the ray sees the front (Geometry >
Backfacing mixes in black): both renderers see the same light.

Cycles settings, both arms: CPU, 2 threads, denoising off, box pixel filter of width 1 px
(wavetrace's box filter, so the two references must agree pixel by pixel), no clamping (direct
and indirect 0; Cycles' default indirect clamp is 10), Filter Glossy 0 (it blurs glossy paths:
a bias), light threshold 0 (no culling of dim lights), bounces up to 1024 of every kind (as
wavetrace's max depth; both play Russian roulette), caustics on. The fixed arm renders with
adaptive sampling off; the adaptive arm with Cycles' default threshold 0.01 (minimum samples
automatic). Time: Cycles' own time limit (`cycles.time_limit`, which excludes the scene sync)
with an unbounded sample count; the seconds in the table are Cycles' own clock from its first
sample pass to its last (path tracing without sync and saving; `wall` adds both), the samples
the last pass it reports. Cycles schedules passes in growing batches from its measured speed
and may overrun the limit when the machine's load rises, so the table also gives the error
times the seconds (inverse efficiency), which is the equal-time ratio whatever the overrun. wavetrace runs as
`examples/equal_time.rs --time` (render time without the scene load: whole passes while the
next fits), fixed (`--noise-threshold` absent) or adaptive (its default threshold 0.05).

Each renderer's image is compared with its own reference by `examples/image_error.rs`
(RMSE, MSE, relative MSE, top-1% share). Arms alternate within each budget and seed.
"""

import argparse
import math
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

import bpy
from blender_common import empty_scene

SIZE = 256
EMISSION = 20.0
FIXED, ADAPTIVE = "fixed", "adaptive"

# scenes/room.toml, vertex orders kept: a face's front is the side its vertices run
# counter-clockwise from, in both formats.
FLOOR = [(-3, 0, -5), (0, -6, -5), (10, -6, -5), (13, 0, -5), (10, 6, -5), (0, 6, -5)]
CEILING = [(0, 6, 5), (10, 6, 5), (13, 0, 5), (10, -6, 5), (0, -6, 5), (-3, 0, 5)]
WALLS = [
    ("wall A-B", "white", [(-3, 0, -5), (-3, 0, 5), (0, -6, 5), (0, -6, -5)]),
    ("wall B-C", "green", [(0, -6, -5), (0, -6, 5), (10, -6, 5), (10, -6, -5)]),
    ("wall C-D", "blue", [(10, -6, -5), (10, -6, 5), (13, 0, 5), (13, 0, -5)]),
    ("wall D-E", "yellow", [(13, 0, -5), (13, 0, 5), (10, 6, 5), (10, 6, -5)]),
    ("wall E-F", "red", [(10, 6, -5), (10, 6, 5), (0, 6, 5), (0, 6, -5)]),
    ("wall F-A", "white", [(0, 6, -5), (0, 6, 5), (-3, 0, 5), (-3, 0, -5)]),
]
LIGHT = [(4, 1, 4.99), (6, 1, 4.99), (6, -1, 4.99), (4, -1, 4.99)]
TETRA = [(5.5, 2.2, -5.0), (4.461, 0.4, -5.0), (6.539, 0.4, -5.0), (5.5, 1.0, -3.0)]
ALBEDOS = {
    "white": (0.8, 0.8, 0.8),
    "green": (0.15, 0.75, 0.15),
    "blue": (0.15, 0.25, 0.8),
    "yellow": (0.8, 0.75, 0.15),
    "red": (0.8, 0.15, 0.15),
    "orange": (0.9, 0.45, 0.1),
}


def principled(name, base, metallic=0.0, roughness=1.0, specular_level=0.0, transmission=0.0):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*base, 1.0)
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Specular IOR Level"].default_value = specular_level
    bsdf.inputs["Transmission Weight"].default_value = transmission
    bsdf.inputs["IOR"].default_value = 1.5
    return mat


def mesh_object(name, vertices, faces, mat, smooth=False):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(map(float, v)) for v in vertices], [], faces)
    mesh.update()
    if smooth:
        mesh.shade_smooth()
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def sphere(name, center, radius, mat):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=128, ring_count=64, radius=radius,
                                         location=center)
    obj = bpy.context.active_object
    obj.name = name
    bpy.ops.object.shade_smooth()
    obj.data.materials.append(mat)
    return obj


def build_scene():
    scene = empty_scene()
    scene.render.resolution_x = SIZE
    scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100

    mats = {name: principled(name, albedo) for name, albedo in ALBEDOS.items()}
    mesh_object("floor", FLOOR, [list(range(6))], mats["white"])
    mesh_object("ceiling", CEILING, [list(range(6))], mats["white"])
    for name, mat, quad in WALLS:
        mesh_object(name, quad, [[0, 1, 2, 3]], mats[mat])

    light = principled("light", (0.0, 0.0, 0.0))
    bsdf = light.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Emission Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bsdf.inputs["Emission Strength"].default_value = EMISSION
    light.use_backface_culling = True  # glTF doubleSided: false, front emission only
    mesh_object("area light", LIGHT, [[0, 1, 2, 3]], light)

    # The tetrahedron's faces, each wound to face outwards.
    centroid = [sum(v[i] for v in TETRA) / 4 for i in range(3)]
    faces = []
    for skip in range(4):
        f = [i for i in range(4) if i != skip]
        a, b, c = (TETRA[i] for i in f)
        u = [b[i] - a[i] for i in range(3)]
        w = [c[i] - a[i] for i in range(3)]
        n = (u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0])
        out = sum(n[i] * (a[i] - centroid[i]) for i in range(3))
        faces.append(f if out > 0 else f[::-1])
    mesh_object("tetrahedron", TETRA, faces, mats["orange"])

    sphere("mirror sphere", (9.0, 3.0, -3.0), 2.0,
           principled("mirror", (1.0, 1.0, 1.0), metallic=1.0, roughness=0.0,
                      specular_level=0.5))
    sphere("glass sphere", (7.0, -2.5, -3.5), 1.5,
           principled("glass", (1.0, 1.0, 1.0), roughness=0.0, specular_level=0.5,
                      transmission=1.0))

    # Pinhole at (-1, 0, 0) looking along +x, z up, 90 degrees (Blender cameras look down
    # their local -z with +y up).
    cam = bpy.data.cameras.new("Camera")
    cam.sensor_fit = "VERTICAL"
    cam.angle = math.radians(90.0)
    cam_obj = bpy.data.objects.new("Camera", cam)
    cam_obj.location = (-1.0, 0.0, 0.0)
    cam_obj.rotation_euler = (math.radians(90.0), 0.0, math.radians(-90.0))
    scene.collection.objects.link(cam_obj)
    scene.camera = cam_obj
    return scene


def front_only_emission(mat):
    """Cycles emits from both sides of a mesh: black where the ray sees the back."""
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    out = nodes["Material Output"]
    bsdf = nodes["Principled BSDF"]
    black = nodes.new("ShaderNodeBsdfDiffuse")
    black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    geometry = nodes.new("ShaderNodeNewGeometry")
    mix = nodes.new("ShaderNodeMixShader")
    links.new(geometry.outputs["Backfacing"], mix.inputs["Fac"])
    links.new(bsdf.outputs["BSDF"], mix.inputs[1])
    links.new(black.outputs["BSDF"], mix.inputs[2])
    links.new(mix.outputs["Shader"], out.inputs["Surface"])


def cycles_settings(scene):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.use_denoising = False
    c.use_preview_denoising = False
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.light_sampling_threshold = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    for attr in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces",
                 "transparent_max_bounces"):
        setattr(c, attr, 1024)
    c.volume_bounces = 0
    scene.render.threads_mode = "FIXED"
    scene.render.threads = os.cpu_count() or 2
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.exr_codec = "ZIP"


def cmd_build(args):
    os.makedirs(args.out, exist_ok=True)
    scene = build_scene()
    glb = os.path.join(args.out, "room.glb")
    bpy.ops.export_scene.gltf(filepath=glb, export_format="GLB", export_cameras=True,
                              export_lights=True)
    front_only_emission(bpy.data.materials["light"])
    cycles_settings(scene)
    blend = os.path.abspath(os.path.join(args.out, "room.blend"))
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    print(f"wrote {glb} and {blend}")


class CyclesRun:
    """Renders a .blend with Cycles; tells the last sample pass Cycles reported."""

    def __init__(self, blend):
        bpy.ops.wm.open_mainfile(filepath=blend)
        self.scene = bpy.context.scene

    def render(self, out, seed, spp=None, seconds=None, adaptive=False):
        s = self.scene
        c = s.cycles
        c.seed = seed
        c.use_adaptive_sampling = adaptive
        c.adaptive_threshold = 0.01  # Cycles' default
        c.adaptive_min_samples = 0  # automatic, as by default
        c.samples = spp if spp else 1 << 24
        c.time_limit = seconds or 0.0
        s.render.filepath = out
        # Blender prints its progress ("Sample N/M") on the process's standard output, and
        # the render_stats handler is not called in background mode: read it from there.
        sys.stdout.flush()
        saved = os.dup(1)
        with tempfile.TemporaryFile() as log:
            os.dup2(log.fileno(), 1)
            try:
                start = time.perf_counter()
                bpy.ops.render.render(write_still=True)
                seconds = time.perf_counter() - start
            finally:
                os.dup2(saved, 1)
                os.close(saved)
            log.seek(0)
            progress = re.findall(rb"Time:(\d+):([\d.]+) .*Sample (\d+)/\d+", log.read())
        # Cycles' own clock from the first sample pass to the last: path tracing without the
        # scene sync (BVH, shaders, lights) and without saving.
        clock = [60 * int(m) + float(sec) for m, sec, _ in progress]
        traced = clock[-1] - clock[0] if clock else float("nan")
        return seconds, max((int(n) for _, _, n in progress), default=0), traced


def image_error(tool, reference, image):
    out = subprocess.run([tool, reference, image], capture_output=True, text=True,
                         check=True).stdout
    m = re.search(r"rmse ([\d.]+) .*mse ([\d.]+), relative mse ([\d.]+), top 1% of pixels "
                  r"hold ([\d.]+)%", out)
    rmse, mse, rel, top = map(float, m.groups())
    return {"rmse": rmse, "mse": mse, "rel": rel, "top": top}


def exr_mean(path):
    img = bpy.data.images.load(os.path.abspath(path), check_existing=False)
    px = img.pixels[:]
    n = img.size[0] * img.size[1]
    means = [sum(px[c::4]) / n for c in range(3)]
    bpy.data.images.remove(img)
    return means, px


def cmd_render(args):
    run = CyclesRun(os.path.abspath(args.blend))
    seconds, spp, traced = run.render(os.path.abspath(args.out), args.seed, spp=args.spp,
                                      seconds=args.time, adaptive=args.adaptive)
    print(f"cycles: {spp} samples (last pass) in {seconds:.2f} s ({traced:.2f} s path "
          f"tracing) -> {args.out}")


def cmd_compare(args):
    """Means of two references per channel and over 4 x 4 regions, with the spread of the
    per-region ratio, so that a difference of units or geometry shows where it is."""
    (ma, pa), (mb, pb) = exr_mean(args.a), exr_mean(args.b)
    for c, name in enumerate("RGB"):
        print(f"{name}: {ma[c]:.5f} vs {mb[c]:.5f}: ratio {ma[c] / mb[c]:.4f}")
    side = int(math.isqrt(len(pa) // 4))
    blocks = 4
    step = side // blocks
    for by in reversed(range(blocks)):  # top row first
        row = []
        for bx in range(blocks):
            sa = sb = 0.0
            for y in range(by * step, (by + 1) * step):
                for x in range(bx * step, (bx + 1) * step):
                    i = 4 * (y * side + x)
                    sa += pa[i] + pa[i + 1] + pa[i + 2]
                    sb += pb[i] + pb[i + 1] + pb[i + 2]
            row.append(f"{sa / sb:.3f}" if sb > 0 else "  -  ")
        print("block ratios: " + " ".join(row))


def wavetrace_run(example, glb, reference, budget, seed, adaptive):
    cmd = [example, glb, "--reference", reference, "--time", f"{budget}s", "--seed", str(seed)]
    if adaptive:
        cmd += ["--noise-threshold", "0.05"]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    line = next(l for l in out.splitlines() if l.startswith("seed "))
    m = re.search(r"([\d.]+) spp, [\d.]+ rays per pixel in ([\d.]+) s: rmse ([\d.]+).*mse ([\d.]+), relative mse "
                  r"([\d.]+), top 1% of pixels hold ([\d.]+)%", line)
    spp, seconds, rmse, mse, rel, top = map(float, m.groups())
    return {"spp": spp, "s": seconds, "rmse": rmse, "mse": mse, "rel": rel, "top": top}


def cmd_table(args):
    example = os.path.join(args.target, "examples", "equal_time")
    error_tool = os.path.join(args.target, "examples", "image_error")
    glb = os.path.join(args.out, "room.glb")
    scratch = os.path.abspath(os.path.join(args.out, "cycles-run.exr"))
    run = CyclesRun(os.path.abspath(os.path.join(args.out, "room.blend")))
    results = {}
    log = open(os.path.join(args.out, "table-runs.txt"), "a")
    for repeat in range(args.repeats):
        seed = 100 + repeat
        for budget in args.budgets:
            order = ("cycles", "wavetrace") if repeat % 2 else ("wavetrace", "cycles")
            # Which renderer goes first alternates with the seed.
            arms = [(r, m) for m in args.modes for r in order]
            for renderer, mode in arms:
                if renderer == "wavetrace":
                    r = wavetrace_run(example, glb, args.wt_ref, budget, seed, mode == ADAPTIVE)
                else:
                    wall, spp, traced = run.render(scratch, seed, seconds=budget,
                                                   adaptive=mode == ADAPTIVE)
                    r = image_error(error_tool, args.cycles_ref, scratch)
                    r.update(spp=float(spp), s=traced, wall=wall)
                results.setdefault((budget, mode, renderer), []).append(r)
                line = f"{budget:g} s {mode} {renderer} seed {seed}: {r}"
                print(line, flush=True)
                log.write(line + "\n")
                log.flush()
    print("\nmedians (spp: wavetrace's mean per pixel; Cycles' last sample pass):")
    print("| budget | sampling | renderer | spp | s | RMSE | MSE | rel. MSE | top 1% | MSE x s "
          "| rel. MSE x s |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    med = {}
    for key in sorted(results):
        runs = results[key]
        for r in runs:  # inverse efficiency: the error times the seconds it took
            r["mse_s"], r["rel_s"] = r["mse"] * r["s"], r["rel"] * r["s"]
        med[key] = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
        m = med[key]
        print(f"| {key[0]:g} s | {key[1]} | {key[2]} | {m['spp']:.1f} | {m['s']:.2f} | "
              f"{m['rmse']:.4f} | {m['mse']:.6f} | {m['rel']:.4f} | {m['top']:.1f}% | "
              f"{m['mse_s']:.5f} | {m['rel_s']:.4f} |")
    print("\nratios wavetrace / Cycles (medians): at the budget, and of the error x seconds "
          "(equal time when a renderer overran its budget)")
    for budget in args.budgets:
        for mode in args.modes:
            w, c = med[(budget, mode, "wavetrace")], med[(budget, mode, "cycles")]
            print(f"{budget:g} s {mode}: MSE {w['mse'] / c['mse']:.3f}, relative MSE "
                  f"{w['rel'] / c['rel']:.3f}; MSE x s {w['mse_s'] / c['mse_s']:.3f}, "
                  f"relative MSE x s {w['rel_s'] / c['rel_s']:.3f}")


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    b = sub.add_parser("build")
    b.add_argument("out")
    r = sub.add_parser("render")
    r.add_argument("blend")
    r.add_argument("out")
    r.add_argument("--spp", type=int)
    r.add_argument("--time", type=float)
    r.add_argument("--seed", type=int, default=7)
    r.add_argument("--adaptive", action="store_true")
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    t = sub.add_parser("table")
    t.add_argument("out")
    t.add_argument("--wt-ref", required=True)
    t.add_argument("--cycles-ref", required=True)
    t.add_argument("--budgets", type=float, nargs="+", default=[8, 32])
    t.add_argument("--repeats", type=int, default=3)
    t.add_argument("--target", default="target/release")
    t.add_argument("--modes", nargs="+", default=[FIXED, ADAPTIVE], choices=[FIXED, ADAPTIVE])
    args = p.parse_args(argv)
    {"build": cmd_build, "render": cmd_render, "compare": cmd_compare, "table": cmd_table}[
        args.cmd](args)
    sys.stdout.flush()
    # bpy's module sometimes hangs at interpreter exit (its threads); nothing is left to do.
    os._exit(0)


if __name__ == "__main__":
    main()
