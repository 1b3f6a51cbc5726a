#!/usr/bin/python3
"""Writes scenarios/meshes/character.obj: the upper body of a character (hips, waist, a back
that bulges at the shoulder blades, shoulders, neck, head) as one closed triangle mesh, the
collider of the cape scene (scenarios/cape_on_character.toml).

    /usr/bin/python3 scripts/make_character_mesh.py [output_dir]

The surface is lofted through horizontal elliptical rings (PROFILE: height y, half-width rx
along x, half-depths towards the front (-z, where the character faces) and the back (+z)), with
SEGMENTS vertices a ring and a vertex at each pole; 12 rings of 32 vertices and 2 poles: 386
vertices, 768 triangles, closed and wound outward (counter-clockwise seen from outside; checked
below by the enclosed volume's sign). Deterministic: running it again gives the same bytes.
Standard library only.
"""

import math
import os
import sys

SEGMENTS = 32
# (y, rx, rz_front, rz_back), m, from the bottom up.
PROFILE = [
    (0.80, 0.130, 0.090, 0.090),  # hips
    (0.90, 0.160, 0.100, 0.110),
    (1.05, 0.150, 0.100, 0.110),  # waist
    (1.20, 0.170, 0.120, 0.150),  # chest; the back bulges at the shoulder blades
    (1.32, 0.200, 0.110, 0.140),
    (1.42, 0.220, 0.100, 0.110),  # shoulders
    (1.48, 0.140, 0.070, 0.070),
    (1.52, 0.055, 0.055, 0.055),  # neck
    (1.58, 0.055, 0.055, 0.055),
    (1.63, 0.085, 0.095, 0.090),  # head
    (1.72, 0.095, 0.100, 0.100),
    (1.80, 0.065, 0.070, 0.070),
]
BOTTOM = (0.0, 0.77, 0.0)
TOP = (0.0, 1.84, 0.0)


def character():
    verts = []
    for y, rx, front, back in PROFILE:
        for j in range(SEGMENTS):
            phi = 2.0 * math.pi * j / SEGMENTS
            s = math.sin(phi)
            verts.append((rx * math.cos(phi), y, (back if s > 0.0 else front) * s))
    bottom = len(verts)
    verts.append(BOTTOM)
    top = len(verts)
    verts.append(TOP)

    def ring(i, j):
        return i * SEGMENTS + j % SEGMENTS

    tris = []
    # Side quads: a (ring i, j), b (ring i + 1, j), c (ring i, j + 1), d (ring i + 1, j + 1);
    # (b - a) x (c - a) is up x (along phi) = outward.
    for i in range(len(PROFILE) - 1):
        for j in range(SEGMENTS):
            a, b, c, d = ring(i, j), ring(i + 1, j), ring(i, j + 1), ring(i + 1, j + 1)
            tris += [(a, b, c), (c, b, d)]
    last = len(PROFILE) - 1
    for j in range(SEGMENTS):
        tris.append((bottom, ring(0, j), ring(0, j + 1)))
        tris.append((ring(last, j), top, ring(last, j + 1)))
    return verts, tris


def enclosed_volume(verts, tris):
    v = 0.0
    for a, b, c in tris:
        pa, pb, pc = verts[a], verts[b], verts[c]
        v += (pa[0] * (pb[1] * pc[2] - pb[2] * pc[1]) - pa[1] * (pb[0] * pc[2] - pb[2] * pc[0])
              + pa[2] * (pb[0] * pc[1] - pb[1] * pc[0])) / 6.0
    return v


def fmt(x):
    return "%.12g" % x


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(os.path.abspath(__file__)), "..", "scenarios", "meshes")
    verts, tris = character()
    volume = enclosed_volume(verts, tris)
    if not volume > 0.0:
        raise SystemExit("character: wound inward (volume %g)" % volume)
    with open(os.path.join(out, "character.obj"), "w") as f:
        f.write("# character: the upper body (hips to head) of the cape scene, lofted through 12\n")
        f.write("# elliptical rings of %d vertices; %d vertices, %d triangles, closed, wound outward,\n"
                % (SEGMENTS, len(verts), len(tris)))
        f.write("# enclosed volume %s m^3. Written by scripts/make_character_mesh.py.\n" % fmt(volume))
        f.write("o character\n")
        for v in verts:
            f.write("v %s %s %s\n" % tuple(fmt(c) for c in v))
        for t in tris:
            f.write("f %d %d %d\n" % tuple(i + 1 for i in t))


if __name__ == "__main__":
    main()
