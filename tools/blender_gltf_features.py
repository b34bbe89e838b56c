"""Writes small glTF files by hand that use one feature each, renders each with wavetrace and
with Cycles after Blender 4.5's own import of the same file, and compares them (a developer
tool, not part of CI).

Cases (`--only NAME`, a prefix):
- `ortho`: an orthographic camera (xmag 3.6, ymag 2.7) looking down at three boxes on a floor
  under a sun; 128 x 96 pixels, the image shape xmag / ymag. Besides the means, the
  silhouettes against the black background: each image thresholded, the pixels where the two
  masks disagree and each mask's bounding box (the framing must match exactly);
- `emit_mask`, `emit_blend`: a double-sided emissive quad above a grey floor whose
  base-colour texture's alpha cuts it (MASK: stripes of alpha 1 and 0, cutoff 0.5, nearest
  filtering) or thins it (BLEND: alpha from 0.25 to 1 across the quad);
- `volume_thin`, `volume_thick`: a smooth glass cube (IOR 1.5, side 1) with attenuation
  colour (0.8, 0.5, 0.2) at distance 1 in front of an emitting wall, without
  `thicknessFactor` (thin-walled) and with 1 (a volume boundary); besides the means, the
  colour through the cube's centre;
- `rough_glass_0.4`, `rough_glass_0.8`: the same cube of clear rough glass (roughness 0.4 and
  0.8, no volume), which Blender's importer makes a Principled BSDF of Blender's default
  distribution, Multiscatter GGX;
- `mip`, `mip_nomip`, `mip_nearest`, `mip_nearest_nomip`: a Lambertian plane with a
  repeating checkerboard (256 x 256 texels, 8-texel squares) seen from 1 unit above it toward
  the horizon under a sun, its sampler's `minFilter` LINEAR_MIPMAP_LINEAR (`mip`) or LINEAR
  (`mip_nomip`, no mipmaps) with `magFilter` LINEAR; or NEAREST_MIPMAP_LINEAR (`mip_nearest`)
  or NEAREST (`mip_nearest_nomip`) with `magFilter` NEAREST, which Blender's importer makes
  Closest. Cycles reads the image without mipmaps and filters by supersampling; it
  interpolates 8-bit sRGB images before decoding them, which darkens a minified checker
  (`mip`, `mip_nomip`); Closest has nothing to interpolate. Besides the means, the RMSE of
  the far rows (the top third of the plane) and of the near rows (the bottom third).

Each case prints the whole-image mean of wavetrace and Cycles, their ratio, and the median
over 8 x 8-pixel blocks of |wavetrace - Cycles| / Cycles. Results go to OUT/results.txt.

    cargo build --release
    /work/scratch/blender/venv/bin/python tools/blender_gltf_features.py -- \
        --wavetrace target/release/wavetrace --out /tmp/features
"""

import argparse
import base64
import json
import math
import os
import struct
import subprocess
import sys
import tempfile
import zlib

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_textures import compare, exr_luma, render_cycles  # noqa: E402


def png_bytes(width, height, texel):
    """An 8-bit RGBA PNG of `texel(x, y) -> (r, g, b, a)` in [0, 1], row 0 at the top (glTF's
    image orientation)."""
    raw = bytearray()
    for y in range(height):
        raw.append(0)
        for x in range(width):
            raw.extend(max(0, min(255, round(255 * c))) for c in texel(x, y))

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
            + chunk(b"IDAT", zlib.compress(bytes(raw))) + chunk(b"IEND", b""))


class Gltf:
    """A glTF document under construction: meshes of quads, materials, textures, nodes, with
    one embedded buffer."""

    def __init__(self):
        self.doc = {"asset": {"version": "2.0", "generator": "wavetrace blender_gltf_features"},
                    "scenes": [{"nodes": []}], "scene": 0, "nodes": [], "meshes": [],
                    "materials": [], "accessors": [], "bufferViews": [], "buffers": [],
                    "extensionsUsed": []}
        self.data = bytearray()

    def use(self, extension):
        if extension not in self.doc["extensionsUsed"]:
            self.doc["extensionsUsed"].append(extension)

    def _accessor(self, values, kind, component, target):
        while len(self.data) % 4:
            self.data.append(0)
        offset = len(self.data)
        width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[kind]
        fmt = "<" + ("f" if component == 5126 else "H") * len(values)
        self.data.extend(struct.pack(fmt, *values))
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": offset,
                                        "byteLength": len(self.data) - offset,
                                        "target": target})
        accessor = {"bufferView": len(self.doc["bufferViews"]) - 1, "componentType": component,
                    "count": len(values) // width, "type": kind}
        if kind == "VEC3" and component == 5126:
            accessor["min"] = [min(values[i::3]) for i in range(3)]
            accessor["max"] = [max(values[i::3]) for i in range(3)]
        self.doc["accessors"].append(accessor)
        return len(self.doc["accessors"]) - 1

    def mesh(self, quads, material):
        """One primitive of `quads`, each (corner, edge u, edge v, uv scale): the quad spans
        corner + s u + t v, its normal u x v, its texture coordinates (s, 1 - t) times the
        scale."""
        pos, nor, uv, idx = [], [], [], []
        for corner, u, v, scale in quads:
            n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
            length = math.sqrt(sum(c * c for c in n))
            base = len(pos) // 3
            for s, t in ((0, 0), (1, 0), (1, 1), (0, 1)):
                pos.extend(corner[i] + s * u[i] + t * v[i] for i in range(3))
                nor.extend(c / length for c in n)
                uv.extend((s * scale, (1 - t) * scale))
            idx.extend(base + k for k in (0, 1, 2, 0, 2, 3))
        attributes = {"POSITION": self._accessor(pos, "VEC3", 5126, 34962),
                      "NORMAL": self._accessor(nor, "VEC3", 5126, 34962),
                      "TEXCOORD_0": self._accessor(uv, "VEC2", 5126, 34962)}
        indices = self._accessor(idx, "SCALAR", 5123, 34963)
        self.doc["meshes"].append({"primitives": [{"attributes": attributes, "indices": indices,
                                                    "material": material}]})
        return len(self.doc["meshes"]) - 1

    def material(self, m):
        self.doc["materials"].append(m)
        for name in m.get("extensions", {}):
            self.use(name)
        return len(self.doc["materials"]) - 1

    def texture(self, png, min_filter, mag_filter):
        self.doc.setdefault("images", []).append(
            {"uri": "data:image/png;base64," + base64.b64encode(png).decode()})
        self.doc.setdefault("samplers", []).append({"minFilter": min_filter,
                                                     "magFilter": mag_filter})
        self.doc.setdefault("textures", []).append(
            {"source": len(self.doc["images"]) - 1, "sampler": len(self.doc["samplers"]) - 1})
        return len(self.doc["textures"]) - 1

    def node(self, node):
        self.doc["nodes"].append(node)
        self.doc["scenes"][0]["nodes"].append(len(self.doc["nodes"]) - 1)

    def save(self, path):
        self.doc["buffers"] = [{"byteLength": len(self.data), "uri":
                                "data:application/octet-stream;base64,"
                                + base64.b64encode(bytes(self.data)).decode()}]
        if not self.doc["extensionsUsed"]:
            del self.doc["extensionsUsed"]
        with open(path, "w") as out:
            json.dump(self.doc, out)


def look_at(eye, target):
    """The column-major matrix of a node at `eye` whose -Z looks at `target`, +Y up."""
    f = [t - e for t, e in zip(target, eye)]
    length = math.sqrt(sum(c * c for c in f))
    z = [-c / length for c in f]
    up = [0.0, 1.0, 0.0]
    x = [up[1] * z[2] - up[2] * z[1], up[2] * z[0] - up[0] * z[2], up[0] * z[1] - up[1] * z[0]]
    length = math.sqrt(sum(c * c for c in x))
    x = [c / length for c in x]
    y = [z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]]
    return x + [0.0] + y + [0.0] + z + [0.0] + list(eye) + [1.0]


def lambert(gltf, colour, **extra):
    """A Lambertian material as Blender reads it: roughness 1, Specular IOR Level 0."""
    m = {"pbrMetallicRoughness": {"baseColorFactor": list(colour) + [1.0], "metallicFactor": 0.0,
                                  "roughnessFactor": 1.0},
         "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}}
    m.update(extra)
    return gltf.material(m)


def floor_quad(half, y=0.0, uv_scale=1.0):
    return ([-half, y, half], [2 * half, 0, 0], [0, 0, -2 * half], uv_scale)


def box(centre, size):
    """The six faces of an axis-aligned box, outward."""
    cx, cy, cz = centre
    sx, sy, sz = (s / 2 for s in size)
    return [
        ([cx - sx, cy - sy, cz + sz], [2 * sx, 0, 0], [0, 2 * sy, 0], 1),  # +z
        ([cx + sx, cy - sy, cz - sz], [-2 * sx, 0, 0], [0, 2 * sy, 0], 1),  # -z
        ([cx + sx, cy - sy, cz + sz], [0, 0, -2 * sz], [0, 2 * sy, 0], 1),  # +x
        ([cx - sx, cy - sy, cz - sz], [0, 0, 2 * sz], [0, 2 * sy, 0], 1),  # -x
        ([cx - sx, cy + sy, cz + sz], [2 * sx, 0, 0], [0, 0, -2 * sz], 1),  # +y
        ([cx - sx, cy - sy, cz - sz], [2 * sx, 0, 0], [0, 0, 2 * sz], 1),  # -y
    ]


def sun(gltf, eye, lux):
    gltf.use("KHR_lights_punctual")
    gltf.doc.setdefault("extensions", {}).setdefault("KHR_lights_punctual", {"lights": []})
    lights = gltf.doc["extensions"]["KHR_lights_punctual"]["lights"]
    lights.append({"type": "directional", "intensity": lux})
    gltf.node({"matrix": look_at(eye, [0.0, 0.0, 0.0]),
               "extensions": {"KHR_lights_punctual": {"light": len(lights) - 1}}})


def build_ortho(path):
    g = Gltf()
    g.node({"mesh": g.mesh([floor_quad(2.5)], lambert(g, (0.5, 0.5, 0.5)))})
    g.node({"mesh": g.mesh(box((-1.2, 0.5, 0.3), (1, 1, 1)), lambert(g, (0.8, 0.2, 0.1)))})
    g.node({"mesh": g.mesh(box((1.0, 1.0, -1.0), (0.6, 2, 0.6)), lambert(g, (0.2, 0.7, 0.2)))})
    g.node({"mesh": g.mesh(box((0.6, 0.25, 1.3), (1.2, 0.5, 0.8)), lambert(g, (0.2, 0.3, 0.8)))})
    sun(g, [2.0, 5.0, 3.0], 683.0 * 3.0)
    g.doc["cameras"] = [{"type": "orthographic", "orthographic": {
        "xmag": 3.6, "ymag": 2.7, "znear": 0.01, "zfar": 100.0}}]
    g.node({"camera": 0, "matrix": look_at([5.0, 4.0, 6.0], [0.0, 0.3, 0.0])})
    g.save(path)
    return 128, 96


def build_emitter(path, mode):
    g = Gltf()
    g.node({"mesh": g.mesh([floor_quad(3.0)], lambert(g, (0.5, 0.5, 0.5)))})
    if mode == "MASK":
        png = png_bytes(16, 16, lambda x, y: (1, 1, 1, 1.0 if (x // 4) % 2 == 0 else 0.0))
        texture = g.texture(png, 9728, 9728)
    else:
        png = png_bytes(16, 16, lambda x, y: (1, 1, 1, 0.25 + 0.75 * x / 15))
        texture = g.texture(png, 9729, 9729)
    emitter = g.material({
        "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0,
                                 "roughnessFactor": 1.0,
                                 "baseColorTexture": {"index": texture}},
        "emissiveFactor": [1.0, 0.9, 0.7], "alphaMode": mode, "doubleSided": True,
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 8.0},
                       "KHR_materials_specular": {"specularFactor": 0.0}}})
    g.node({"mesh": g.mesh([([-1.0, 1.2, 1.0], [2, 0, 0], [0, 0, -2], 1)], emitter)})
    g.doc["cameras"] = [{"type": "perspective", "perspective": {
        "yfov": math.radians(50.0), "aspectRatio": 4 / 3, "znear": 0.01}}]
    g.node({"camera": 0, "matrix": look_at([0.0, 2.4, 5.0], [0.0, 0.3, 0.0])})
    g.save(path)
    return 128, 96


def build_mip(path, min_filter, mag_filter=9729):
    g = Gltf()
    png = png_bytes(256, 256, lambda x, y: (0.9, 0.9, 0.9, 1) if ((x // 8) + (y // 8)) % 2
                    else (0.1, 0.1, 0.1, 1))
    texture = g.texture(png, min_filter, mag_filter)
    checker = g.material({
        "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0.0,
                                 "roughnessFactor": 1.0, "baseColorTexture": {"index": texture}},
        "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}})
    # 200 units square, the texture repeating every 4 units.
    g.node({"mesh": g.mesh([floor_quad(100.0, uv_scale=50.0)], checker)})
    sun(g, [0.3, 1.0, 0.2], 683.0 * 3.0)
    g.doc["cameras"] = [{"type": "perspective", "perspective": {
        "yfov": math.radians(40.0), "aspectRatio": 2.0, "znear": 0.01}}]
    g.node({"camera": 0, "matrix": look_at([0.0, 1.0, 0.0], [0.0, 1.0, -10.0])})
    g.save(path)
    return 128, 64


def build_volume(path, thickness, roughness=0.0, attenuation=True):
    g = Gltf()
    backdrop = g.material({
        "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0},
        "emissiveFactor": [1.0, 1.0, 1.0], "doubleSided": True,
        "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}})
    g.node({"mesh": g.mesh([([-4.0, -3.5, -2.0], [8, 0, 0], [0, 8, 0], 1)], backdrop)})
    volume = {"attenuationColor": [0.8, 0.5, 0.2], "attenuationDistance": 1.0}
    if thickness > 0.0:
        volume["thicknessFactor"] = thickness
    extensions = {"KHR_materials_transmission": {"transmissionFactor": 1.0}}
    if attenuation:
        extensions["KHR_materials_volume"] = volume
    glass = g.material({
        "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0.0,
                                 "roughnessFactor": roughness},
        "extensions": extensions})
    g.node({"mesh": g.mesh(box((0.0, 0.5, 0.0), (1, 1, 1)), glass)})
    g.doc["cameras"] = [{"type": "perspective", "perspective": {
        "yfov": math.radians(30.0), "aspectRatio": 1.0, "znear": 0.01}}]
    g.node({"camera": 0, "matrix": look_at([0.0, 0.5, 4.0], [0.0, 0.5, 0.0])})
    g.save(path)
    return 96, 96


def import_for_cycles(path, width, height):
    """Blender's factory settings without objects or world (black), the file imported by
    Blender's glTF importer, its camera made the scene's; punctual lights as imported (a sun
    of angle 0)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.import_scene.gltf(filepath=path)
    for obj in scene.objects:
        if obj.type == "CAMERA":
            scene.camera = obj
        if obj.type == "LIGHT" and obj.data.type == "SUN":
            obj.data.angle = 0.0
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    return scene


def silhouettes(ours, cycles, threshold):
    """Pixels whose masks (luminance above `threshold`) disagree, and each mask's bounding box
    (x0, y0, x1, y1), rows from the top."""
    w, h, a = ours
    _, _, b = cycles

    def bbox(px):
        inside = [(i % w, i // w) for i in range(w * h) if px[i] > threshold]
        xs, ys = [p[0] for p in inside], [p[1] for p in inside]
        return (min(xs), min(ys), max(xs), max(ys)) if inside else None

    disagree = sum((a[i] > threshold) != (b[i] > threshold) for i in range(w * h))
    return disagree, bbox(a), bbox(b)


def exr_channels(path, pixels):
    """The mean R, G, B of `pixels` (indices, rows from the bottom as Blender stores them)."""
    img = bpy.data.images.load(path, check_existing=False)
    px = list(img.pixels)
    bpy.data.images.remove(img)
    return [sum(px[4 * i + c] for i in pixels) / len(pixels) for c in range(3)]


def row_rmse(ours, cycles, rows):
    w, _, a = ours
    _, _, b = cycles
    idx = [y * w + x for y in rows for x in range(w)]
    return math.sqrt(sum((a[i] - b[i]) ** 2 for i in idx) / len(idx))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--wavetrace", required=True)
    ap.add_argument("--out", default=None)
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--only", default=None)
    ap.add_argument("--extra", default="", help="more wavetrace arguments, space separated")
    args = ap.parse_args(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else None)
    out = args.out or tempfile.mkdtemp(prefix="blender-features-")
    os.makedirs(out, exist_ok=True)
    exe = os.path.abspath(args.wavetrace)
    cases = {
        "ortho": build_ortho,
        "emit_mask": lambda p: build_emitter(p, "MASK"),
        "emit_blend": lambda p: build_emitter(p, "BLEND"),
        "mip": lambda p: build_mip(p, 9987),
        "mip_nomip": lambda p: build_mip(p, 9729),
        "mip_nearest": lambda p: build_mip(p, 9986, 9728),
        "mip_nearest_nomip": lambda p: build_mip(p, 9728, 9728),
        "volume_thin": lambda p: build_volume(p, 0.0),
        "volume_thick": lambda p: build_volume(p, 1.0),
        "rough_glass_0.4": lambda p: build_volume(p, 0.0, 0.4, attenuation=False),
        "rough_glass_0.8": lambda p: build_volume(p, 0.0, 0.8, attenuation=False),
    }
    lines = []
    for name, build in cases.items():
        if args.only and not name.startswith(args.only):
            continue
        gltf_path = os.path.join(out, f"{name}.gltf")
        width, height = build(gltf_path)
        cyc = os.path.join(out, f"{name}-cycles.exr")
        if not os.path.exists(cyc):
            render_cycles(import_for_cycles(gltf_path, width, height), cyc, args.samples, 1.5)
        ours = os.path.join(out, f"{name}-wavetrace.exr")
        subprocess.run(
            [exe, "render", gltf_path, "-o", ours, "--width", str(width), "--height",
             str(height), "--spp", str(args.samples), "--quiet"] + args.extra.split(),
            check=True,
        )
        a, b = exr_luma(ours), exr_luma(cyc)
        ma, mb, median = compare(a, b)
        line = (f"{name}: wavetrace {ma:.5f} cycles {mb:.5f} ratio {ma / mb:.4f} "
                f"median block error {median:.4f}")
        if name == "ortho":
            disagree, box_a, box_b = silhouettes(a, b, 0.02)
            line += (f"; silhouettes: {disagree} of {width * height} pixels differ, "
                     f"bounding box wavetrace {box_a} cycles {box_b}")
        if name.startswith("mip"):
            # The horizon is the middle row; the plane fills the lower half (Blender's rows
            # go up from the bottom).
            far = range(height // 2 - height // 6, height // 2)
            near = range(height // 6)
            line += (f"; RMSE far rows {row_rmse(a, b, far):.4f} near rows "
                     f"{row_rmse(a, b, near):.4f}")
        if name.startswith("volume") or name.startswith("rough_glass"):
            # The cube's front face fills the central 24 x 24 pixels or more.
            centre = [y * width + x for y in range(height // 2 - 12, height // 2 + 12)
                      for x in range(width // 2 - 12, width // 2 + 12)]
            rgb = [exr_channels(p, centre) for p in (ours, cyc)]
            line += "; cube centre R G B wavetrace %s cycles %s" % tuple(
                " ".join(f"{c:.4f}" for c in means) for means in rgb)
        lines.append(line)
        print(line, flush=True)
    with open(os.path.join(out, "results.txt"), "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
