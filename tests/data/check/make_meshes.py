#!/usr/bin/env python3
"""Writes the small meshes of tests/data/check/ (OFF, triangles only).

Coordinates are float32 values written with 17 significant digits, so a
reader that parses doubles (meshcheck) and one that stores floats (tessel)
see exactly the same numbers. The NAME.expected files next to them are the
output of the independent evaluator meshcheck (not part of this project):

    meshcheck NAME.off > NAME.expected     (for every NAME.off but the two below)
    meshcheck hole.off --input sphere_cloud.off --ref sphere_fine.off \
        --samples 20000 > hole_vs_sphere.expected
    meshcheck sphere.off --input sphere_cloud.off --ref sphere_fine.off \
        --samples 20000 > sphere_vs_fine.expected

tests/test_check.c compares tessel_mesh_check() with them.
"""
import math
import os
import random
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def f32(x):
    return struct.unpack('f', struct.pack('f', x))[0]


def write_off(name, verts, faces):
    with open(os.path.join(HERE, name), 'w') as f:
        f.write('OFF\n%d %d 0\n' % (len(verts), len(faces)))
        for v in verts:
            f.write(' '.join('%.17g' % f32(c) for c in v) + '\n')
        for t in faces:
            f.write('3 %d %d %d\n' % tuple(t))


def icosphere(levels, radius=1.0, shift=(0.0, 0.0, 0.0)):
    t = (1.0 + math.sqrt(5.0)) / 2.0
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
         (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    v = [tuple(c / math.sqrt(sum(x * x for x in p)) for c in p) for p in v]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(levels):
        mid = {}

        def m(a, b):
            k = (min(a, b), max(a, b))
            if k not in mid:
                p = [(v[a][i] + v[b][i]) / 2 for i in range(3)]
                n = math.sqrt(sum(x * x for x in p))
                v.append(tuple(x / n for x in p))
                mid[k] = len(v) - 1
            return mid[k]
        nf = []
        for a, b, c in f:
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = nf
    v = [tuple(radius * p[i] + shift[i] for i in range(3)) for p in v]
    return v, f


OCT_V = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
OCT_F = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]


def torus(nu, nv, R=2.0, r=0.75):
    v, f = [], []
    for i in range(nu):
        for j in range(nv):
            a, b = 2 * math.pi * i / nu, 2 * math.pi * j / nv
            v.append(((R + r * math.cos(b)) * math.cos(a), (R + r * math.cos(b)) * math.sin(a),
                      r * math.sin(b)))
    for i in range(nu):
        for j in range(nv):
            p, q = i * nv + j, ((i + 1) % nu) * nv + j
            p1, q1 = i * nv + (j + 1) % nv, ((i + 1) % nu) * nv + (j + 1) % nv
            f += [(p, q, q1), (p, q1, p1)]
    return v, f


def main():
    sv, sf = icosphere(2)
    write_off('sphere.off', sv, sf)
    # two holes: one triangle removed, and two adjacent ones elsewhere
    hf = [t for k, t in enumerate(sf) if k not in (0, 100, 103)]
    write_off('hole.off', sv, hf)
    fv, ff = icosphere(3, radius=1.02)
    write_off('sphere_fine.off', fv, ff)
    # the input cloud: the sphere's vertices plus three stray points
    write_off('sphere_cloud.off', sv + [(0.0, 0.0, 1.25), (0.5, 0.5, 0.0), (0.0, -1.5, 0.5)], [])

    tv, tf = torus(12, 8)
    write_off('torus.off', tv, tf)

    # a fin: two triangles of a square plus a third on their common edge
    write_off('nm_edge.off', [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0.5, 0.5, 1)],
              [(0, 1, 2), (0, 2, 3), (0, 2, 4)])

    # two closed tetrahedra touching at one vertex
    tet = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    tet_f = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    v2 = tet + [(-x, -y, -z) for (x, y, z) in tet[1:]]
    f2 = tet_f + [tuple(0 if i == 0 else i + 3 for i in t) for t in tet_f]
    write_off('nm_vertex.off', v2, f2)

    write_off('flipped.off', OCT_V, [(0, 4, 2)] + OCT_F[1:])
    write_off('duplicate.off', OCT_V, OCT_F + [(4, 1, 2)])
    # a zero-area triangle (collinear, distinct indices) and a repeated index
    write_off('degenerate.off', OCT_V + [(0.5, 0, 0)], OCT_F + [(0, 6, 1), (2, 2, 4)])
    tv2 = [(x + 3, y, z) for (x, y, z) in tet]
    write_off('two_components.off', OCT_V + tv2,
              OCT_F + [tuple(i + 6 for i in t) for t in tet_f])

    # Crossing configurations, each group far from the others.
    cv, cf = [], []

    def add(points, tris):
        base = len(cv)
        cv.extend(points)
        cf.extend(tuple(base + i for i in t) for t in tris)
    # 1. two triangles crossing through each other (no shared vertex)
    add([(0, 0, 0), (2, 0, 0), (1, 2, 0), (1, 1, -1), (1, 1, 1), (1, 3, 0)], [(0, 1, 2), (3, 4, 5)])
    # 2. sharing one vertex, the opposite edge of one pierces the other
    add([(10, 0, 0), (12, 0, 0), (11, 2, 0), (11, 1, -1), (11, 1, 1)], [(0, 1, 2), (0, 3, 4)])
    # 3. sharing an edge, coplanar, folded onto the same side
    add([(20, 0, 0), (22, 0, 0), (21, 2, 0), (21, 1, 0)], [(0, 1, 2), (1, 0, 3)])
    # 4. a vertex of one touching the inside of the other (no shared index)
    add([(30, 0, 0), (32, 0, 0), (31, 2, 0), (31, 0.5, 0), (31, 0.5, 1), (32, 1, 1)],
        [(0, 1, 2), (3, 4, 5)])
    # 5. sharing an edge, coplanar, on opposite sides: fine
    add([(40, 0, 0), (42, 0, 0), (41, 2, 0), (41, -2, 0)], [(0, 1, 2), (1, 0, 3)])
    # 6. sharing a vertex through a bit-identical duplicate vertex: fine
    add([(50, 0, 0), (52, 0, 0), (51, 2, 0), (50, 0, 0), (50, -2, 0), (48, -1, 0)],
        [(0, 1, 2), (3, 4, 5)])
    # 7. coplanar overlap without a shared vertex
    add([(60, 0, 0), (62, 0, 0), (61, 2, 0), (60.5, 0.5, 0), (62.5, 0.5, 0), (61.5, 2.5, 0)],
        [(0, 1, 2), (3, 4, 5)])
    # 8. nearly touching but separate (a gap of 2^-20)
    add([(70, 0, 0), (72, 0, 0), (71, 2, 0), (71, 0.5, 2 ** -20), (71, 0.5, 1), (72, 1, 1)],
        [(0, 1, 2), (3, 4, 5)])
    write_off('crossing.off', cv, cf)

    # Random soups on a coarse integer grid: many touching, coplanar and
    # collinear configurations and bit-identical vertices.
    rng = random.Random(12345)
    sv, sf = [], []
    while len(sf) < 150:
        p = [tuple(rng.randint(0, 6) for _ in range(3)) for _ in range(3)]
        if len(set(p)) < 3:
            continue
        sf.append((len(sv), len(sv) + 1, len(sv) + 2))
        sv.extend(p)
    write_off('soup.off', sv, sf)
    sv, sf = [], []
    while len(sf) < 150:
        p = [(rng.randint(0, 5), rng.randint(0, 5), 0) for _ in range(3)]
        if len(set(p)) < 3:
            continue
        sf.append((len(sv), len(sv) + 1, len(sv) + 2))
        sv.extend(p)
    write_off('soup_planar.off', sv, sf)


if __name__ == '__main__':
    main()
