"""Renders a brushed-metal quad (KHR_materials_anisotropy) with wavetrace and with Cycles
after Blender's own glTF import of the same file, and compares them (a developer tool, not
part of CI).

The scene, written here as a .gltf: a 2 x 2 metal quad (base colour 0.9, roughness 0.4)
facing up, with texture coordinates and an anisotropy texture of one texel (direction 0.4 rad
from the tangent, blue 1) rotated by `anisotropyRotation` 0.3 rad, and an emissive quad
(doubly sided, strength 5) above and behind it whose reflection the camera sees. With the
texture, Blender's importer wires a UV-map Tangent node into the Principled BSDF, so both
renderers orient the anisotropy by the same UV tangent frame (without it, Blender's
Principled BSDF falls back to its radial default tangent, which glTF does not describe).

Cases (`--only NAME`):
- `iso`: strength 0, the isotropic baseline (checks the scene, the light and the camera);
- `blender`: strength 0.8 in a file whose `asset.generator` says Blender's exporter wrote
  it: wavetrace follows Cycles' mapping (docs/importing.md, "Anisotropy");
- `gltf`: the same file from another generator: wavetrace follows the glTF specification's
  mapping, Blender's importer still Cycles' (the difference between the two, measured).

Each case prints the whole-image mean of wavetrace and Cycles, their ratio, and the median
over 8 x 8-pixel blocks of |wavetrace - Cycles| / Cycles. Results go to OUT/results.txt.

    cargo build --release
    /tmp/bpy/bin/python tools/blender_anisotropy.py --wavetrace target/release/wavetrace
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
from blender_common import empty_scene
from blender_textures import compare, exr_luma, render_cycles

BLENDER_GENERATOR = "Khronos glTF Blender I/O v4.5.15"


def write_png(path, width, height, texel):
    """An 8-bit RGB PNG from `texel(x, y) -> (r, g, b)` bytes."""
    rows = b"".join(
        b"\0" + bytes(c for x in range(width) for c in texel(x, y)) for y in range(height)
    )

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header))
        f.write(chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def quad(y, x0, x1, z0, z1, up):
    """Positions, normals, UVs (u along +x, v along +z) and indices of a quad at height y."""
    p = [(x0, y, z0), (x1, y, z0), (x1, y, z1), (x0, y, z1)]
    n = [(0.0, 1.0 if up else -1.0, 0.0)] * 4
    uv = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    idx = [0, 2, 1, 0, 3, 2] if up else [0, 1, 2, 0, 2, 3]
    return p, n, uv, idx


def write_gltf(path, strength, generator):
    """The scene (module doc) as `path`, its texture beside it."""
    texture_angle = 0.4
    r = round((math.cos(texture_angle) + 1.0) / 2.0 * 255.0)
    g = round((math.sin(texture_angle) + 1.0) / 2.0 * 255.0)
    png = os.path.join(os.path.dirname(path), "anisotropy.png")
    write_png(png, 2, 2, lambda x, y: (r, g, 255))
    blob, views, accessors, meshes = bytearray(), [], [], []

    def add(values, kind, fmt, target):
        offset = len(blob)
        for v in values:
            blob.extend(struct.pack(fmt, *v) if isinstance(v, tuple) else struct.pack(fmt, v))
        while len(blob) % 4:
            blob.append(0)
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(blob) - offset,
                      "target": target})
        accessor = {"bufferView": len(views) - 1, "count": len(values),
                    "componentType": 5125 if kind == "SCALAR" else 5126, "type": kind}
        if kind == "VEC3" and fmt == "<3f":
            accessor["min"] = [min(v[i] for v in values) for i in range(3)]
            accessor["max"] = [max(v[i] for v in values) for i in range(3)]
        accessors.append(accessor)
        return len(accessors) - 1

    for material, (p, n, uv, idx) in [
        (0, quad(0.0, -1.0, 1.0, -1.0, 1.0, True)),
        (1, quad(1.0, -0.6, 0.6, -2.3, -1.7, False)),
    ]:
        attributes = {
            "POSITION": add(p, "VEC3", "<3f", 34962),
            "NORMAL": add(n, "VEC3", "<3f", 34962),
            "TEXCOORD_0": add(uv, "VEC2", "<2f", 34962),
        }
        indices = add(idx, "SCALAR", "<I", 34963)
        meshes.append({"primitives": [{"attributes": attributes, "indices": indices,
                                       "material": material}]})
    tilt = -math.atan2(1.2, 2.5)
    doc = {
        "asset": {"version": "2.0", "generator": generator},
        "extensionsUsed": ["KHR_materials_anisotropy", "KHR_materials_emissive_strength"],
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [
            {"mesh": 0, "name": "brushed"},
            {"mesh": 1, "name": "lamp"},
            {"camera": 0, "name": "camera", "translation": [0.0, 1.2, 2.5],
             "rotation": [math.sin(tilt / 2), 0.0, 0.0, math.cos(tilt / 2)]},
        ],
        "cameras": [{"type": "perspective",
                     "perspective": {"yfov": 0.7, "aspectRatio": 1.0, "znear": 0.05}}],
        "meshes": meshes,
        "materials": [
            {"name": "brushed metal",
             "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.9, 0.9, 1.0],
                                      "metallicFactor": 1.0, "roughnessFactor": 0.4},
             "extensions": {"KHR_materials_anisotropy": {
                 "anisotropyStrength": strength, "anisotropyRotation": 0.3,
                 "anisotropyTexture": {"index": 0}}}},
            {"name": "lamp", "doubleSided": True,
             "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0],
                                      "metallicFactor": 0.0},
             "emissiveFactor": [1.0, 1.0, 1.0],
             "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 5.0}}},
        ],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728}],
        "images": [{"uri": "anisotropy.png"}],
        "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                     + base64.b64encode(bytes(blob)).decode()}],
        "bufferViews": views,
        "accessors": accessors,
    }
    with open(path, "w") as f:
        json.dump(doc, f, indent=1)


def cycles_of_import(gltf, path, size, samples):
    """Cycles' render of Blender's import of `gltf` (black world, the file's camera)."""
    scene = empty_scene(radiance=0.0)
    bpy.ops.import_scene.gltf(filepath=gltf)
    scene.camera = next(o for o in scene.objects if o.type == "CAMERA")
    scene.render.resolution_x = scene.render.resolution_y = size
    render_cycles(scene, path, samples)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--wavetrace", required=True)
    ap.add_argument("--out", default=None)
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--only", default=None)
    args = ap.parse_args(sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else None)
    out = args.out or tempfile.mkdtemp(prefix="blender-anisotropy-")
    os.makedirs(out, exist_ok=True)
    exe = os.path.abspath(args.wavetrace)
    cases = {
        "iso": (0.0, BLENDER_GENERATOR),
        "blender": (0.8, BLENDER_GENERATOR),
        "gltf": (0.8, "hand-written"),
    }
    lines = []
    for name, (strength, generator) in cases.items():
        if args.only and not name.startswith(args.only):
            continue
        gltf = os.path.join(out, f"{name}.gltf")
        write_gltf(gltf, strength, generator)
        cyc = os.path.join(out, f"{name}-cycles.exr")
        if not os.path.exists(cyc):
            cycles_of_import(gltf, cyc, args.size, args.samples)
        ours = os.path.join(out, f"{name}-wavetrace.exr")
        subprocess.run(
            [exe, "render", gltf, "-o", ours, "--width", str(args.size), "--height",
             str(args.size), "--spp", str(args.samples), "--quiet"],
            check=True,
        )
        ma, mb, median = compare(exr_luma(ours), exr_luma(cyc))
        lines.append(f"{name}: wavetrace {ma:.5f} cycles {mb:.5f} ratio {ma / mb:.4f} "
                     f"median block error {median:.4f}")
        print(lines[-1], flush=True)
    with open(os.path.join(out, "results.txt"), "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
