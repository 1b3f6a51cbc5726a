#!/usr/bin/python3
"""Writes the small example meshes in scenarios/meshes/ used by the tests and example scenarios.

    /usr/bin/python3 scripts/make_example_meshes.py [output_dir]

Outputs (deterministic: running it again gives the same bytes):
  icosphere.obj        icosahedron subdivided once and projected onto a sphere of radius 0.1 m
                       centred at the origin: 42 vertices, 80 triangles, closed, wound outward
                       (counter-clockwise seen from outside).
  box.node, box.ele    TetGen files, 1-based, of the box [0, 0.2]^3 m split into 2 x 2 x 2 cubic
                       cells of 0.1 m, 6 tets per cell (the split along each cell's main diagonal):
                       27 vertices, 48 tets, all positively oriented.
  box.msh              the same box as a Gmsh ASCII 4.1 file.
Standard library only.
"""

import itertools
import math
import os
import sys

RADIUS = 0.1  # m, icosphere radius
CELLS = 2  # cells per axis of the box
CELL = 0.1  # m, cell edge


def icosphere():
    """(vertices, triangles) of the once-subdivided icosahedron on a sphere of RADIUS."""
    t = (1.0 + math.sqrt(5.0)) / 2.0
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0),
             (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
             (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11),
             (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8),
             (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
             (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]

    def project(p):
        n = math.sqrt(sum(c * c for c in p))
        return tuple(RADIUS * c / n for c in p)

    verts = [project(v) for v in verts]
    midpoint = {}

    def mid(a, b):
        key = (min(a, b), max(a, b))
        if key not in midpoint:
            pa, pb = verts[a], verts[b]
            verts.append(project(tuple((x + y) / 2.0 for x, y in zip(pa, pb))))
            midpoint[key] = len(verts) - 1
        return midpoint[key]

    subdivided = []
    for a, b, c in faces:
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        subdivided += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
    # Wind every triangle outward: its normal must point away from the centre.
    for i, (a, b, c) in enumerate(subdivided):
        pa, pb, pc = verts[a], verts[b], verts[c]
        u = [pb[k] - pa[k] for k in range(3)]
        v = [pc[k] - pa[k] for k in range(3)]
        n = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
        if sum(n[k] * (pa[k] + pb[k] + pc[k]) for k in range(3)) < 0.0:
            subdivided[i] = (a, c, b)
    return verts, subdivided


def box():
    """(vertices, tets) of the box: vertex (i, j, k) has index i + 3 j + 9 k (0-based)."""
    m = CELLS + 1
    verts = [(i * CELL, j * CELL, k * CELL)
             for k in range(m) for j in range(m) for i in range(m)]

    def vid(i, j, k):
        return i + m * (j + m * k)

    tets = []
    for k, j, i in itertools.product(range(CELLS), repeat=3):
        corner = [vid(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1)) for b in range(8)]
        # One tet per path 000 -> 111 along the axes (x: bit 1, y: bit 2, z: bit 4).
        for order in itertools.permutations((1, 2, 4)):
            path = [0, order[0], order[0] + order[1], 7]
            tet = [corner[b] for b in path]
            if signed_volume([verts[v] for v in tet]) < 0.0:
                tet[2], tet[3] = tet[3], tet[2]
            tets.append(tet)
    return verts, tets


def signed_volume(p):
    a = [p[1][k] - p[0][k] for k in range(3)]
    b = [p[2][k] - p[0][k] for k in range(3)]
    c = [p[3][k] - p[0][k] for k in range(3)]
    return (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6.0


def fmt(x):
    return "%.12g" % x


def write_obj(path, verts, tris):
    with open(path, "w") as f:
        f.write("# icosphere: radius 0.1 m, icosahedron subdivided once; 42 vertices, 80 triangles,\n")
        f.write("# closed and wound outward. Written by scripts/make_example_meshes.py.\n")
        f.write("o icosphere\n")
        for v in verts:
            f.write("v %s %s %s\n" % tuple(fmt(c) for c in v))
        for t in tris:
            f.write("f %d %d %d\n" % tuple(i + 1 for i in t))


def write_tetgen(base, verts, tets):
    with open(base + ".node", "w") as f:
        f.write("# box [0, 0.2]^3 m, 2 x 2 x 2 cells. Written by scripts/make_example_meshes.py.\n")
        f.write("# <points> <dimension> <attributes> <boundary markers>\n")
        f.write("%d 3 0 1\n" % len(verts))
        for i, v in enumerate(verts):
            on_boundary = any(c == 0.0 or abs(c - CELLS * CELL) < 1e-12 for c in v)
            f.write("%d %s %s %s %d\n" % ((i + 1,) + tuple(fmt(c) for c in v) + (int(on_boundary),)))
    with open(base + ".ele", "w") as f:
        f.write("# <tetrahedra> <nodes per tetrahedron> <attributes>\n")
        f.write("%d 4 0\n" % len(tets))
        for e, t in enumerate(tets):
            f.write("%d %d %d %d %d\n" % ((e + 1,) + tuple(i + 1 for i in t)))


def write_gmsh41(path, verts, tets):
    lo, hi = 0.0, CELLS * CELL
    with open(path, "w") as f:
        f.write("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n")
        # One volume entity, no lower-dimensional entities.
        f.write("$Entities\n0 0 0 1\n1 %s %s %s %s %s %s 0 0\n$EndEntities\n"
                % tuple(fmt(c) for c in (lo, lo, lo, hi, hi, hi)))
        n = len(verts)
        f.write("$Nodes\n1 %d 1 %d\n3 1 0 %d\n" % (n, n, n))
        for i in range(n):
            f.write("%d\n" % (i + 1))
        for v in verts:
            f.write("%s %s %s\n" % tuple(fmt(c) for c in v))
        f.write("$EndNodes\n")
        m = len(tets)
        f.write("$Elements\n1 %d 1 %d\n3 1 4 %d\n" % (m, m, m))
        for e, t in enumerate(tets):
            f.write("%d %d %d %d %d\n" % ((e + 1,) + tuple(i + 1 for i in t)))
        f.write("$EndElements\n")


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(root, "scenarios", "meshes")
    os.makedirs(out, exist_ok=True)
    verts, tris = icosphere()
    assert len(verts) == 42 and len(tris) == 80
    write_obj(os.path.join(out, "icosphere.obj"), verts, tris)
    verts, tets = box()
    assert len(verts) == 27 and len(tets) == 48
    assert abs(sum(signed_volume([verts[v] for v in t]) for t in tets) - (CELLS * CELL) ** 3) < 1e-15
    write_tetgen(os.path.join(out, "box"), verts, tets)
    write_gmsh41(os.path.join(out, "box.msh"), verts, tets)


if __name__ == "__main__":
    main()
