#!/usr/bin/env python3
"""Renders a wavetrace scene file of the seed room's kind (polygons, quads, tetrahedra,
spheres; diffuse, mirror, dielectric and emitting materials) with Mitsuba 3, and compares
renders with a reference, to check a hypothesis about wavetrace's noise against another
renderer (project issue 22). Needs `python3 -m pip install mitsuba` (variant llvm_ad_rgb,
which needs libLLVM, or scalar_rgb).

    python3 tools/mitsuba_room.py render scenes/room.toml out.exr --spp 16 --seed 1 \
        [--size 128] [--filter box|gaussian] [--rr-depth 5] [--variant llvm_ad_rgb]
    python3 tools/mitsuba_room.py error reference.exr a.exr [b.exr ...] [--mirror]

The `error` figures follow wavetrace's `image_error` definitions (MSE over pixels and
channels; relative MSE with `ref^2 + 0.01` in the denominator; the share of the squared error
held by the worst 1% of pixels). `--mirror` flips each image left to right before comparing,
for a Mitsuba render against a wavetrace reference if Mitsuba's image comes out mirrored
(check that the unflipped error is the larger). `--block N` averages the reference over
N x N blocks first: a box-filtered reference at 1/N of its size (for smaller renders).
"""

import argparse
import os
import sys
import tempfile
import tomllib


def triangles_of(shape):
    """The shape's triangles as vertex triples, front = counter-clockwise seen from outside."""
    kind = shape["type"]
    v = [tuple(float(c) for c in p) for p in shape["vertices"]]
    if kind in ("polygon", "quad"):
        return [(v[0], v[i], v[i + 1]) for i in range(1, len(v) - 1)]
    if kind == "tetrahedron":
        centre = tuple(sum(p[a] for p in v) / 4 for a in range(3))
        faces = []
        for skip in range(4):
            a, b, c = [p for i, p in enumerate(v) if i != skip]
            n = cross(sub(b, a), sub(c, a))
            if dot(n, sub(a, centre)) < 0:  # normal toward the inside: flip
                b, c = c, b
            faces.append((a, b, c))
        return faces
    raise SystemExit(f"shape type '{kind}' is not exported")


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def write_obj(path, triangles):
    with open(path, "w") as f:
        for t in triangles:
            for p in t:
                f.write("v %r %r %r\n" % p)
        for i in range(len(triangles)):
            f.write("f %d %d %d\n" % (3 * i + 1, 3 * i + 2, 3 * i + 3))


def bsdf_of(material):
    kind = material["type"]
    if kind == "diffuse":
        # wavetrace's Lambert reflects on both sides
        return {"type": "twosided", "nested": {"type": "diffuse", "reflectance": {
            "type": "rgb", "value": material.get("albedo", [0.8, 0.8, 0.8])}}}
    if kind == "mirror":
        return {"type": "conductor", "material": "none"}
    if kind == "dielectric":
        return {"type": "dielectric", "int_ior": float(material.get("ior", 1.5)), "ext_ior": 1.0}
    raise SystemExit(f"material type '{kind}' is not exported")


def scene_dict(scene, workdir, size, spp, filter_name, rr_depth):
    cam = scene["camera"]
    import mitsuba as mi
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": -1, "rr_depth": rr_depth},
        "sensor": {
            "type": "perspective",
            "fov": float(cam.get("vfov", 90.0)),
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(
                origin=cam["eye"], target=cam["look_at"], up=cam["up"]),
            "film": {"type": "hdrfilm", "width": size, "height": size,
                     "rfilter": {"type": filter_name}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        },
    }
    materials = scene["materials"]
    for i, shape in enumerate(scene["shape"]):
        material = materials[shape["material"]]
        bsdf = bsdf_of(material)
        if shape["type"] == "sphere":
            entry = {"type": "sphere", "center": [float(c) for c in shape["center"]],
                     "radius": float(shape["radius"]), "bsdf": bsdf}
        else:
            path = os.path.join(workdir, f"shape{i}.obj")
            write_obj(path, triangles_of(shape))
            entry = {"type": "obj", "filename": path, "face_normals": True, "bsdf": bsdf}
        if "emission" in shape:  # one-sided, toward the front, as wavetrace's default
            entry["emitter"] = {"type": "area", "radiance": {
                "type": "rgb", "value": [float(c) for c in shape["emission"]]}}
        d[f"shape{i}"] = entry
    return d


def render(args):
    import mitsuba as mi
    mi.set_variant(args.variant)
    with open(args.scene, "rb") as f:
        scene = tomllib.load(f)
    with tempfile.TemporaryDirectory() as workdir:
        loaded = mi.load_dict(scene_dict(scene, workdir, args.size, args.spp, args.filter,
                                         args.rr_depth))
        import time
        start = time.time()
        image = mi.render(loaded, seed=args.seed)
        import drjit as dr
        dr.eval(image)
        dr.sync_thread()  # the LLVM backend runs kernels asynchronously
        seconds = time.time() - start
    mi.util.write_bitmap(args.output, image)
    print(f"{args.output}: {args.size}x{args.size}, {args.spp} spp, filter {args.filter}, "
          f"rr_depth {args.rr_depth}, {seconds:.2f} s")


def error(args):
    import mitsuba as mi
    mi.set_variant(args.variant)

    def load(path):
        return mi.TensorXf(mi.Bitmap(path).convert(mi.Bitmap.PixelFormat.RGB,
                                                  mi.Struct.Type.Float32, srgb_gamma=False))

    import numpy as np
    reference = np.array(load(args.reference), dtype=np.float64)
    if args.block > 1:
        h, w, c = reference.shape
        n = args.block
        reference = reference.reshape(h // n, n, w // n, n, c).mean(axis=(1, 3))
    for path in args.images:
        image = np.array(load(path), dtype=np.float64)
        if args.mirror:
            image = image[:, ::-1, :]
        d2 = np.square(image - reference)
        mse = d2.mean()
        relative = (d2 / (np.square(reference) + 0.01)).mean()
        # The worst 1% of pixels (at least one), as wavetrace's image_error.
        per_pixel = np.sort(d2.sum(axis=2).ravel())
        top = max(per_pixel.size // 100, 1)
        share = per_pixel[-top:].sum() / per_pixel.sum() if per_pixel.sum() > 0 else 0.0
        print(f"{path}: mse {mse:.6f}, relative mse {relative:.5f}, "
              f"top 1% of pixels hold {100 * share:.1f}% of the squared error")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub_parsers = parser.add_subparsers(dest="command", required=True)
    r = sub_parsers.add_parser("render")
    r.add_argument("scene")
    r.add_argument("output")
    r.add_argument("--spp", type=int, default=16)
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--size", type=int, default=128)
    r.add_argument("--filter", choices=["box", "gaussian"], default="gaussian")
    r.add_argument("--rr-depth", type=int, default=5)
    r.add_argument("--variant", default="llvm_ad_rgb")
    e = sub_parsers.add_parser("error")
    e.add_argument("reference")
    e.add_argument("images", nargs="+")
    e.add_argument("--variant", default="llvm_ad_rgb")
    e.add_argument("--mirror", action="store_true")
    e.add_argument("--block", type=int, default=1)
    args = parser.parse_args()
    {"render": render, "error": error}[args.command](args)


if __name__ == "__main__":
    sys.exit(main())
