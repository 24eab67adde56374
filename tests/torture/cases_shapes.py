"""Class shapes: hostile inputs for the commands that make designs from shapes (rods-from-mesh,
rods-from-cad): truncated and lying binary STL headers, OFF/PLY headers declaring billions of
elements, non-finite and huge coordinates, indices out of range, degenerate and non-manifold meshes,
a mesh that is only a fin, binary garbage under every extension, a FIFO as input, --max-memory far
below a large mesh, an interrupt during the simplification of a big mesh, and STEP/IGES garbage.
Every one must end with exit 1 (bad file) or 2 (bad option) and a message naming the file or option,
never a signal, a hang, a runaway or a half-written design."""

from __future__ import annotations

import math
import signal
import struct
from pathlib import Path

from engine import Case, Step
from fixtures import fifo

TETRA_V = [(0, 0, 0), (10, 0, 0), (0, 10, 0), (0, 0, 10)]
TETRA_F = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def binary_stl(triangles: list[tuple], declared: int | None = None) -> bytes:
    out = b"torture".ljust(80, b" ") + struct.pack("<I", len(triangles) if declared is None else declared)
    for t in triangles:
        out += struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *p) for p in t) + b"\0\0"
    return out


def tetra_triangles(v=TETRA_V) -> list[tuple]:
    return [tuple(v[i] for i in f) for f in TETRA_F]


def obj(vertices, faces) -> str:
    return "".join(f"v {x} {y} {z}\n" for x, y, z in vertices) + "".join("f " + " ".join(str(i) for i in f) + "\n" for f in faces)


def sphere_obj(n: int, radius: float = 20.0) -> str:
    """A UV sphere with n rings and 2n segments, closed at the poles (about 4 n^2 triangles)."""
    vs = [(0.0, 0.0, radius)]
    for i in range(1, n):
        th = math.pi * i / n
        for j in range(2 * n):
            ph = math.pi * j / n
            vs.append((radius * math.sin(th) * math.cos(ph), radius * math.sin(th) * math.sin(ph), radius * math.cos(th)))
    vs.append((0.0, 0.0, -radius))
    m = 2 * n
    ring = lambda i, j: 2 + (i - 1) * m + j % m  # 1-based OBJ index of ring i (1..n-1), segment j
    fs = [(1, ring(1, j), ring(1, j + 1)) for j in range(m)]
    for i in range(1, n - 1):
        for j in range(m):
            fs += [(ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)), (ring(i, j), ring(i + 1, j + 1), ring(i, j + 1))]
    south = len(vs)
    fs += [(ring(n - 1, j), south, ring(n - 1, j + 1)) for j in range(m)]
    return obj(vs, fs)


def mesh_case(name: str, file: str, content, patterns=(), faces: int = 4, expect=frozenset({1}), note: str = "",
              extra: list[str] = (), timeout: float = 60) -> Case:
    argv = ["rods-from-mesh", file, "--faces", str(faces), "--diameter", "1", "-o", "d.json", *extra]
    return Case(name, [Step(argv, expect=set(expect), where=[file], patterns=list(patterns), outputs=["d.json"],
                            timeout=timeout)], files={file: content}, note=note)


def cases(ctx) -> list[Case]:
    cs: list[Case] = []
    good = tetra_triangles()
    # Binary STL whose header lies about its size, truncated, or holds garbage.
    cs.append(mesh_case("stl-declares-4-billion", "m.stl", binary_stl(good, declared=0xFFFFFFFF), note="count 2^32-1, 4 triangles"))
    cs.append(mesh_case("stl-truncated", "m.stl", binary_stl(good)[:-30], expect={0, 1}, note="last triangle cut"))
    cs.append(mesh_case("stl-only-header", "m.stl", b"x" * 84, note="header, no triangles"))
    cs.append(mesh_case("stl-nan", "m.stl", binary_stl(tetra_triangles([(0, 0, 0), (10, 0, 0), (0, float("nan"), 0), (0, 0, 10)])),
                        ["finite"], note="a NaN coordinate"))
    cs.append(mesh_case("stl-inf", "m.stl", binary_stl(tetra_triangles([(0, 0, 0), (float("inf"), 0, 0), (0, 10, 0), (0, 0, 10)])),
                        ["finite"], note="an infinite coordinate"))
    cs.append(mesh_case("stl-huge-coordinates", "m.stl", binary_stl(tetra_triangles([(0, 0, 0), (3e38, 0, 0), (0, 3e38, 0), (0, 0, 3e38)])),
                        ["1e9"], note="coordinates near float's limit"))
    cs.append(mesh_case("stl-all-one-point", "m.stl", binary_stl([((1, 1, 1),) * 3] * 4), ["degenerate"], note="zero-size triangles"))
    ascii_overflow = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1e999 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid x\n"
    cs.append(mesh_case("stl-ascii-1e999", "m.stl", ascii_overflow, ["line 5", "1e999"], note="a coordinate beyond double"))
    cs.append(mesh_case("obj-nan-spelled", "m.obj", "v 0 0 0\nv 1 0 0\nv 0 NaN 0\nv 0 0 1\nf 1 2 3\n", ["line 3", "NaN"],
                        note="a vertex coordinate spelled NaN"))
    cs.append(mesh_case("stl-ascii-garbage", "m.stl", "solid x\nfacet normal banana\n", note="broken ASCII STL"))
    # OBJ/OFF/PLY lies and breakage.
    cs.append(mesh_case("obj-index-out-of-range", "m.obj", obj(TETRA_V, [(1, 2, 99)]), note="face refers to vertex 99 of 4"))
    cs.append(mesh_case("obj-negative-index-far", "m.obj", obj(TETRA_V, [(1, 2, -99)]), note="relative index before the first vertex"))
    cs.append(mesh_case("obj-two-corner-face", "m.obj", obj(TETRA_V, [(1, 2)]), note="a face of 2 corners"))
    cs.append(mesh_case("obj-fin", "m.obj", obj(TETRA_V + [(0, -10, 0)], [(1, 2, 3), (2, 1, 5), (1, 2, 4)]), ["non-manifold"],
                        note="three triangles on one edge"))
    cs.append(mesh_case("obj-duplicate-face", "m.obj", obj(TETRA_V, [(1, 3, 2), (1, 2, 4), (1, 4, 3), (2, 3, 4), (2, 3, 4)]),
                        ["non-manifold"], note="a face listed twice"))
    cs.append(mesh_case("obj-mobius", "m.obj", obj([(math.cos(2 * math.pi * i / 6) * (10 + s), math.sin(2 * math.pi * i / 6) * (10 + s),
                                                     s * (1 if i % 2 else -1)) for i in range(6) for s in (-2, 2)],
                                                    [(2 * i + 1, 2 * i + 2, 2 * ((i + 1) % 6) + 1 + (1 if i == 5 else 0)) for i in range(6)]),
                        expect={0, 1}, note="a twisted strip"))
    cs.append(mesh_case("off-declares-billions", "m.off", "OFF\n2000000000 2000000000 0\n0 0 0\n", ["OFF header"],
                        note="counts no file can hold"))
    cs.append(mesh_case("off-negative-counts", "m.off", "OFF\n-4 -4 0\n", note="negative counts"))
    cs.append(mesh_case("off-face-of-2-billion-corners", "m.off", "OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n2000000000 0 1 2\n",
                        expect={1}, note="a face declaring 2e9 corners"))
    cs.append(mesh_case("ply-declares-billions", "m.ply",
                        "ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\n"
                        "element face 4000000000\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n", note="4e9 elements"))
    cs.append(mesh_case("ply-binary-truncated", "m.ply",
                        b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                        b"element face 4\nproperty list uchar int vertex_indices\nend_header\n" + b"\0" * 20, note="binary body cut short"))
    for ext in ("stl", "obj", "ply", "off"):
        cs.append(mesh_case(f"garbage-{ext}", f"m.{ext}", bytes(range(256)) * 16, note="binary garbage"))
        cs.append(mesh_case(f"empty-{ext}", f"m.{ext}", b"", ["empty"], note="empty file"))
    cs.append(mesh_case("fifo-input", "m.obj", fifo, ["regular file"], note="a FIFO named like a mesh", timeout=10))
    cs.append(mesh_case("directory-input", "m.stl", lambda p, c: p.mkdir(), ["regular file"], note="a folder named like a mesh"))
    cs.append(mesh_case("unknown-extension", "m.3ds", "x", ["unknown mesh format"]))
    # A legal mesh with more faces asked than it has, and --max-memory far below a big mesh's needs.
    sphere = sphere_obj(40)
    cs.append(mesh_case("more-faces-than-the-mesh", "s.obj", sphere, ["fewer than"], faces=100000))
    cs.append(mesh_case("max-memory-too-small", "s.obj", sphere_obj(400), ["memory"], faces=100,
                        extra=["--max-memory", "64M"], timeout=120, note="640,000 triangles in 64 MiB"))
    # Interrupt while a big mesh is simplified: exit 130, no design left behind. At 3.5 s: the collapses
    # (about 6 s of this mesh on an idle machine, polled per collapse and while collecting). At 1 s a
    # loaded machine was still orienting the triangles (CGAL's orient_polygon_soup, 0.5 s that cannot
    # poll), which the watchdog cut short.
    cs.append(Case("interrupt-during-simplification",
                   [Step(["rods-from-mesh", "s.obj", "--faces", "200", "--diameter", "1", "-o", "d.json"], outputs=["d.json"],
                         signal=(signal.SIGINT, 3.5), timeout=120)],
                   files={"s.obj": sphere_obj(300)}, note="SIGINT after 3.5 s of 360,000 triangles"))
    # Options.
    for bad in (["--faces", "0"], ["--faces", "-5"], ["--faces", "99999999999"], ["--subdivisions", "100000"],
                ["--diameter", "inf"], ["--surface-tolerance", "-1"], ["--breadth", "1"]):
        cs.append(Case(f"mesh-option{'-'.join(bad)}", [Step(["rods-from-mesh", "s.obj", "--diameter", "1", "-o", "d.json", *bad],
                                                        expect={2}, where=[bad[0]], outputs=["d.json"])],
                       files={"s.obj": obj(TETRA_V, [(1, 3, 2), (1, 2, 4), (1, 4, 3), (2, 3, 4)])}))
    # CAD: garbage under both extensions, an ISO-10303 header with nothing after it, binary noise.
    for name, content in [("m.step", "ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\n#1=CARTESIAN_POINT('',(0.,0.,1e999));\nENDSEC;\n"),
                          ("m.stp", bytes(range(256)) * 64), ("m.iges", "S      1\n" * 3), ("m.igs", b"\xff" * 4096),
                          ("m.step", "")]:
        cs.append(Case(f"cad-{name}-{len(content)}", [Step(["rods-from-cad", name, "--diameter", "1", "-o", "d.json"],
                                                         expect={1}, where=[name], outputs=["d.json"], timeout=60)],
                       files={name: content}, note="not a usable CAD model"))
    cs.append(Case("cad-fifo", [Step(["rods-from-cad", "m.step", "--diameter", "1", "-o", "d.json"], expect={1}, where=["m.step"],
                                     outputs=["d.json"], timeout=10)], files={"m.step": fifo}))
    return cs
