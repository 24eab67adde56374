#!/usr/bin/env python3
"""Draws a rod design over the mesh it was made from, as an SVG (orthographic view, no dependencies):
the mesh's triangles shaded by their normal, back to front, and the rods' control polygons' curves
sampled as polylines on top (drawn where they face the viewer).

    python3 examples/render_rods_on_mesh.py MESH.obj DESIGN.json OUT.svg [AZIMUTH_DEGREES]
"""
import json
import math
import sys


def bspline_points(c, n=24):
    """Samples a NURBS centerline (de Boor on the homogeneous points)."""
    p, knots, pts = c["degree"], c["knots"], c["points"]
    w = c.get("weights", [1.0] * len(pts))
    lo, hi = knots[p], knots[len(pts)]
    out = []
    for s in range(n + 1):
        u = lo + (hi - lo) * s / n
        k = max(i for i in range(p, len(pts)) if knots[i] <= u) if u < hi else len(pts) - 1
        d = [[pts[j][0] * w[j], pts[j][1] * w[j], pts[j][2] * w[j], w[j]] for j in range(k - p, k + 1)]
        for r in range(1, p + 1):
            for j in range(p, r - 1, -1):
                i = j + k - p
                den = knots[i + p - r + 1] - knots[i]
                a = 0 if den == 0 else (u - knots[i]) / den
                d[j] = [(1 - a) * d[j - 1][t] + a * d[j][t] for t in range(4)]
        out.append([d[p][t] / d[p][3] for t in range(3)])
    return out


def main():
    mesh_file, design_file, out_file = sys.argv[1:4]
    az = math.radians(float(sys.argv[4]) if len(sys.argv) > 4 else -60)
    vs, fs = [], []
    for line in open(mesh_file):
        t = line.split()
        if t and t[0] == "v":
            vs.append([float(x) for x in t[1:4]])
        elif t and t[0] == "f":
            fs.append([int(x.split("/")[0]) - 1 for x in t[1:4]])
    view = [math.cos(az), math.sin(az), 0.35]  # towards the viewer
    n = math.sqrt(sum(x * x for x in view))
    view = [x / n for x in view]
    right = [-math.sin(az), math.cos(az), 0.0]
    up = [view[1] * right[2] - view[2] * right[1], view[2] * right[0] - view[0] * right[2], view[0] * right[1] - view[1] * right[0]]
    dot = lambda a, b: sum(x * y for x, y in zip(a, b))
    proj = lambda p: (dot(p, right), -dot(p, up), dot(p, view))
    P = [proj(v) for v in vs]
    xs, ys = [p[0] for p in P], [p[1] for p in P]
    scale = 560 / max(max(xs) - min(xs), max(ys) - min(ys))
    X = lambda p: 20 + (p[0] - min(xs)) * scale
    Y = lambda p: 20 + (p[1] - min(ys)) * scale
    svg = [f'<svg xmlns="http://www.w3.org/2000/svg" width="600" height="{int(40 + (max(ys) - min(ys)) * scale)}">',
           '<rect width="100%" height="100%" fill="white"/>']
    tris = []
    for f in fs:
        a, b, c = (vs[i] for i in f)
        nrm = [(b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1]), (b[2] - a[2]) * (c[0] - a[0]) - (b[0] - a[0]) * (c[2] - a[2]),
               (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])]
        ln = math.sqrt(dot(nrm, nrm)) or 1
        facing = dot(nrm, view) / ln
        if facing > 0:
            tris.append((sum(P[i][2] for i in f) / 3, f, facing))
    for _, f, facing in sorted(tris):
        g = int(150 + 90 * facing)
        svg.append('<polygon points="' + " ".join(f"{X(P[i]):.1f},{Y(P[i]):.1f}" for i in f) + f'" fill="rgb({g},{g},{g})"/>')
    depth_front = sorted(P, key=lambda p: p[2])
    for rod in json.load(open(design_file))["rods"]:
        q = [proj(p) for p in bspline_points(rod["centerline"])]
        mid = q[len(q) // 2]
        # Draw rods on the visible side: at least as near the viewer as the mesh's middle depth there.
        if mid[2] < depth_front[len(depth_front) // 2][2] - 5:
            continue
        svg.append('<polyline fill="none" stroke="rgb(200,40,30)" stroke-width="2" points="' +
                   " ".join(f"{X(p):.1f},{Y(p):.1f}" for p in q) + '"/>')
    svg.append("</svg>")
    open(out_file, "w").write("\n".join(svg))


main()
