#!/usr/bin/env python3
"""Writes the small hand-made assets of this directory (standard library only):

  vase.obj / vase.mtl  a lathe-turned vase (smooth normals, UVs, textured with checker.png)
                       and a five-pointed star plate (concave 10-gon caps: tests ear clipping;
                       `illum 3` -> mirror), +Y up like Blender's OBJ exports
  checker.png          8 x 8 sRGB checker in two colours

Run from anywhere: python3 assets/make_assets.py
"""
import math
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))


def write_png(path, width, height, rows):
    raw = b"".join(b"\x00" + bytes(row) for row in rows)

    def chunk(kind, data):
        c = struct.pack(">I", len(data)) + kind + data
        return c + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n"
    png += chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 9))
    png += chunk(b"IEND", b"")
    with open(path, "wb") as f:
        f.write(png)


def checker():
    a, b = (230, 200, 120), (60, 90, 160)
    rows = []
    for y in range(8):
        row = []
        for x in range(8):
            row.extend(a if (x + y) % 2 == 0 else b)
        rows.append(row)
    write_png(os.path.join(HERE, "checker.png"), 8, 8, rows)


def vase(lines, offset):
    # Profile (radius, height) from the bottom centre up to the lip; revolved in 24 steps.
    profile = [(0.0, 0.0), (0.45, 0.0), (0.6, 0.25), (0.7, 0.6), (0.62, 1.0), (0.38, 1.35),
               (0.3, 1.6), (0.36, 1.85), (0.42, 1.95)]
    steps = 24
    lines.append("o Vase")
    verts, normals, uvs = [], [], []
    for i, (r, h) in enumerate(profile):
        # Profile tangent -> outward normal in the (r, h) plane.
        r0, h0 = profile[max(i - 1, 0)]
        r1, h1 = profile[min(i + 1, len(profile) - 1)]
        tr, th = r1 - r0, h1 - h0
        nr, nh = th, -tr
        length = math.hypot(nr, nh) or 1.0
        nr, nh = nr / length, nh / length
        for s in range(steps + 1):
            a = 2 * math.pi * s / steps
            verts.append((r * math.cos(a), h, -r * math.sin(a)))
            normals.append((nr * math.cos(a), nh, -nr * math.sin(a)))
            uvs.append((2 * s / steps, h / 1.95))
    for v in verts:
        lines.append("v %.6f %.6f %.6f" % v)
    for n in normals:
        lines.append("vn %.6f %.6f %.6f" % n)
    for t in uvs:
        lines.append("vt %.6f %.6f" % t)
    lines.append("usemtl vase")
    row = steps + 1
    for i in range(len(profile) - 1):
        for s in range(steps):
            a = offset + i * row + s
            b, c, d = a + 1, a + row + 1, a + row
            if profile[i][0] == 0.0:
                lines.append("f %d/%d/%d %d/%d/%d %d/%d/%d" % (a, a, a, c, c, c, d, d, d))
            else:
                lines.append("f %d/%d/%d %d/%d/%d %d/%d/%d %d/%d/%d"
                             % (a, a, a, b, b, b, c, c, c, d, d, d))
    return offset + len(verts)


def star(lines, offset):
    # A five-pointed star plate, 0.15 thick, beside the vase; caps are concave 10-gons.
    lines.append("o Star")
    pts = []
    for k in range(10):
        a = math.pi / 2 + k * math.pi / 5
        r = 0.8 if k % 2 == 0 else 0.33
        pts.append((1.5 + r * math.cos(a), -r * math.sin(a)))
    for y in (0.0, 0.15):
        for x, z in pts:
            lines.append("v %.6f %.6f %.6f" % (x, y, z))
    lines.append("usemtl star")
    bottom = [offset + k for k in range(10)]
    top = [offset + 10 + k for k in range(10)]
    # Seen from above (+y), the points run counter-clockwise: top cap as is, bottom reversed.
    lines.append("f " + " ".join(str(i) for i in top))
    lines.append("f " + " ".join(str(i) for i in reversed(bottom)))
    for k in range(10):
        a, b = bottom[k], bottom[(k + 1) % 10]
        lines.append("f %d %d %d %d" % (a, b, b + 10, a + 10))
    return offset + 20


def main():
    checker()
    lines = ["# wavetrace assets/make_assets.py: a vase and a star plate, +Y up", "mtllib vase.mtl"]
    offset = vase(lines, 1)
    star(lines, offset)
    with open(os.path.join(HERE, "vase.obj"), "w") as f:
        f.write("\n".join(lines) + "\n")
    with open(os.path.join(HERE, "vase.mtl"), "w") as f:
        f.write("# wavetrace assets/make_assets.py\n"
                "newmtl vase\nKd 1 1 1\nmap_Kd checker.png\nillum 1\n\n"
                "newmtl star\nKd 0 0 0\nKs 0.95 0.9 0.8\nNs 1000\nillum 3\n")


if __name__ == "__main__":
    main()
