#!/usr/bin/python3
"""Writes scenarios/meshes/pole.obj, the thin horizontal pole of scenarios/cloth_on_pole.toml.

    /usr/bin/python3 scripts/make_pole_mesh.py [output_dir]

A regular 16-sided prism of circumradius 0.03 m along x from -0.5 to 0.5 m, its axis through
the origin, closed by two fan caps: 34 vertices (the 2 x 16 ring vertices, then the two cap
centres), 64 triangles, wound outward (counter-clockwise seen from outside). Deterministic:
running it again gives the same bytes. Standard library only.
"""

import math
import os
import sys

SIDES = 16
RADIUS = 0.03  # m
HALF_LENGTH = 0.5  # m


def pole():
    verts = []
    for x in (-HALF_LENGTH, HALF_LENGTH):
        for k in range(SIDES):
            a = 2.0 * math.pi * k / SIDES
            verts.append((x, RADIUS * math.cos(a), RADIUS * math.sin(a)))
    verts.append((-HALF_LENGTH, 0.0, 0.0))
    verts.append((HALF_LENGTH, 0.0, 0.0))
    left, right = 2 * SIDES, 2 * SIDES + 1
    faces = []
    for k in range(SIDES):
        k1 = (k + 1) % SIDES
        a, b, c, d = k, k1, SIDES + k, SIDES + k1
        # The side quad (a, b at x = -L; c, d at x = +L), split in two.
        faces += [(a, b, d), (a, d, c)]
        faces.append((left, b, a))  # the cap at -x, seen from -x counter-clockwise
        faces.append((right, c, d))  # the cap at +x
    # Check the winding: each normal points away from the axis (sides) or along +-x (caps).
    for f in faces:
        p = [verts[i] for i in f]
        u = [p[1][i] - p[0][i] for i in range(3)]
        v = [p[2][i] - p[0][i] for i in range(3)]
        n = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
        c = [sum(q[i] for q in p) / 3.0 for i in range(3)]
        cap = left in f or right in f
        out = (c[0], 0.0, 0.0) if cap else (0.0, c[1], c[2])
        assert sum(n[i] * out[i] for i in range(3)) > 0.0, f
    return verts, faces


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(os.path.abspath(__file__)), "..", "scenarios", "meshes")
    verts, faces = pole()
    lines = [
        "# pole: a regular %d-sided prism of circumradius %g m along x from %g to %g m, closed by"
        % (SIDES, RADIUS, -HALF_LENGTH, HALF_LENGTH),
        "# fan caps; %d vertices, %d triangles, wound outward. Written by scripts/make_pole_mesh.py."
        % (len(verts), len(faces)),
        "o pole",
    ]
    lines += ["v %.12g %.12g %.12g" % v for v in verts]
    lines += ["f %d %d %d" % (a + 1, b + 1, c + 1) for a, b, c in faces]
    with open(os.path.join(out_dir, "pole.obj"), "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
