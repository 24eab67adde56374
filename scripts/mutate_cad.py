#!/usr/bin/env python3
"""Mutation fuzzing of `rodfab rods-from-cad`, without coverage feedback (OpenCASCADE is not built for it).

usage: scripts/mutate_cad.py BUILD_DIR OUTDIR [COUNT=2000] [SEED=1] [JOBS=2]

Seeds: make_test_cad's box, circle and spline in STEP and IGES (written into OUTDIR/seeds) and
tests/fuzz/seeds/cad/*.step (a wireframe of conics, polylines, composite, offset and rational curves;
an offset curve and a degree-9 Bezier, which rods-from-cad approximates).
Each case applies 1-4 token mutations to a seed (numbers to extremes, references re-pointed, entity
types swapped, list items dropped or doubled, entities deleted or copied, IGES fields changed, lines
dropped or doubled, truncation, byte flips) and runs rods-from-cad on it under a 6 GB address-space
limit and a 60 s timeout. Expected: exit 0 with a design, or exit 1 without one. A crash of OpenCASCADE
contained by the reader process (an exit 1 saying "crashed on this file") is kept in OUTDIR as
caseN.EXT.contained; anything else (another exit code, a timeout, a design written on failure) is kept
as caseN.EXT, printed as BAD, and makes the script exit 1. Prints the count of each outcome."""
import os, random, re, subprocess, sys, concurrent.futures as cf

build, outdir = sys.argv[1], sys.argv[2]
count = int(sys.argv[3]) if len(sys.argv) > 3 else 2000
seed = int(sys.argv[4]) if len(sys.argv) > 4 else 1
jobs = int(sys.argv[5]) if len(sys.argv) > 5 else 2
rodfab = os.path.join(build, 'slicer', 'rodfab')
seeddir = os.path.join(outdir, 'seeds')
os.makedirs(seeddir, exist_ok=True)
for shape in ('box', 'circle', 'spline'):
    for ext in ('step', 'iges'):
        subprocess.run([os.path.join(build, 'tests', 'make_test_cad'), shape, os.path.join(seeddir, shape + '.' + ext)],
                       check=True, capture_output=True)
here = os.path.dirname(os.path.abspath(__file__))
extra = os.path.join(here, '..', 'tests', 'fuzz', 'seeds', 'cad')
seeds = [(f, open(os.path.join(d, f), 'rb').read()) for d in (seeddir, extra) for f in sorted(os.listdir(d))]

NUMS = [b'0', b'0.', b'-0.', b'1', b'-1', b'1.E308', b'-1.E308', b'1.E-308', b'1.E400', b'2147483647', b'2147483648',
        b'-2147483649', b'4294967296', b'99999999999', b'3', b'7', b'25', b'26', b'1000000', b'1.E-320', b'.5', b'1.5E', b'E5']
TYPES = [b'LINE', b'CIRCLE', b'ELLIPSE', b'HYPERBOLA', b'PARABOLA', b'TRIMMED_CURVE', b'POLYLINE', b'COMPOSITE_CURVE',
         b'COMPOSITE_CURVE_SEGMENT', b'OFFSET_CURVE_3D', b'B_SPLINE_CURVE_WITH_KNOTS', b'SURFACE_CURVE', b'SEAM_CURVE',
         b'PCURVE', b'EDGE_CURVE', b'VERTEX_POINT', b'CARTESIAN_POINT', b'DIRECTION', b'VECTOR', b'AXIS2_PLACEMENT_3D',
         b'GEOMETRIC_CURVE_SET', b'PLANE', b'CYLINDRICAL_SURFACE', b'SURFACE_OF_REVOLUTION', b'SURFACE_OF_LINEAR_EXTRUSION',
         b'ORIENTED_EDGE', b'EDGE_LOOP', b'FACE_BOUND', b'ADVANCED_FACE', b'CLOSED_SHELL', b'MANIFOLD_SOLID_BREP',
         b'B_SPLINE_SURFACE_WITH_KNOTS', b'DEFINITIONAL_REPRESENTATION', b'BOUNDED_CURVE', b'RATIONAL_B_SPLINE_CURVE',
         b'CONICAL_SURFACE', b'SPHERICAL_SURFACE', b'TOROIDAL_SURFACE', b'OFFSET_SURFACE', b'SHELL_BASED_SURFACE_MODEL',
         b'OPEN_SHELL', b'ORIENTED_CLOSED_SHELL', b'BREP_WITH_VOIDS', b'CONNECTED_EDGE_SET', b'EDGE_BASED_WIREFRAME_MODEL',
         b'GEOMETRICALLY_BOUNDED_WIREFRAME_SHAPE_REPRESENTATION', b'MAPPED_ITEM', b'REPRESENTATION_MAP', b'ITEM_DEFINED_TRANSFORMATION',
         b'CARTESIAN_TRANSFORMATION_OPERATOR_3D', b'QUASI_UNIFORM_CURVE', b'UNIFORM_CURVE', b'BEZIER_CURVE']
ENUMS = [b'.T.', b'.F.', b'.U.', b'.UNSPECIFIED.', b'.PARAMETER.', b'.CARTESIAN.', b'.CONTINUOUS.', b'.DISCONTINUOUS.', b'$', b'*']

num_re = re.compile(rb'(?<![#A-Za-z_0-9.])-?\d+\.?\d*(?:E[-+]?\d+)?')
ref_re = re.compile(rb'#\d+')
type_re = re.compile(rb'\b[A-Z][A-Z0-9_]{2,}\b')
enum_re = re.compile(rb'\.[A-Z_]+\.|\$|\*')
list_re = re.compile(rb'\([^()]*\)')


def pick(rng, regex, data):
    ms = list(regex.finditer(data))
    return rng.choice(ms) if ms else None


def step_mutation(rng, d):
    op = rng.randrange(11)
    if op == 0:
        m = pick(rng, num_re, d)
        if m: return d[:m.start()] + rng.choice(NUMS) + d[m.end():]
    elif op == 1:
        m = pick(rng, ref_re, d)
        ids = [int(x[1:]) for x in ref_re.findall(d)] or [1]
        new = rng.choice([rng.choice(ids), rng.choice(ids) + 1, 0, 999999999, rng.randrange(1, 500)])
        if m: return d[:m.start()] + b'#%d' % new + d[m.end():]
    elif op == 2:
        m = pick(rng, type_re, d)
        if m: return d[:m.start()] + rng.choice(TYPES) + d[m.end():]
    elif op == 3:
        m = pick(rng, enum_re, d)
        if m: return d[:m.start()] + rng.choice(ENUMS) + d[m.end():]
    elif op == 4:  # drop or duplicate a list element
        m = pick(rng, list_re, d)
        if m:
            items = m.group(0)[1:-1].split(b',')
            if rng.random() < 0.5 and len(items) > 1: items.pop(rng.randrange(len(items)))
            else:
                i = rng.randrange(len(items))
                items.insert(i, items[i])
            return d[:m.start()] + b'(' + b','.join(items) + b')' + d[m.end():]
    elif op == 5:  # delete an entity
        ents = list(re.finditer(rb'#\d+ = [^;]*;\n', d))
        if ents:
            m = rng.choice(ents)
            return d[:m.start()] + d[m.end():]
    elif op == 6:  # copy an entity's body onto another id
        ents = list(re.finditer(rb'(#\d+) = ([^;]*;)', d))
        if len(ents) > 1:
            a, b = rng.sample(ents, 2)
            return d[:b.start()] + b.group(1) + b' = ' + a.group(2) + d[b.end():]
    elif op == 7:  # truncate
        return d[:rng.randrange(len(d))]
    elif op == 8:  # byte flips
        d = bytearray(d)
        for _ in range(rng.randrange(1, 4)):
            d[rng.randrange(len(d))] = rng.randrange(256)
        return bytes(d)
    elif op == 9:  # an empty list, or a parameter removed
        m = pick(rng, list_re, d)
        if m: return d[:m.start()] + rng.choice([b'()', b'', b'(())', b'($)']) + d[m.end():]
    else:  # swap two references
        ms = list(ref_re.finditer(d))
        if len(ms) > 1:
            a, b = sorted(rng.sample(ms, 2), key=lambda m: m.start())
            return d[:a.start()] + b.group(0) + d[a.end():b.start()] + a.group(0) + d[b.end():]
    return d


def iges_mutation(rng, d):
    lines = d.split(b'\n')
    op = rng.randrange(7)
    if op <= 2:  # a number in a P (parameter) or D (directory) line, keeping the 80-column frame
        cand = [i for i, l in enumerate(lines) if len(l) >= 73 and l[72:73] in b'PD']
        if cand:
            i = rng.choice(cand)
            body = lines[i][:64] if lines[i][72:73] == b'P' else lines[i][:72]
            ms = list(re.finditer(rb'-?\d+\.?\d*(?:E[-+]?\d+)?', body))
            if ms:
                m = rng.choice(ms)
                new = rng.choice(NUMS + [b'126', b'128', b'100', b'110', b'124', b'102', b'104', b'106', b'112', b'116',
                                         b'118', b'120', b'122', b'130', b'141', b'142', b'143', b'144', b'186', b'308', b'402', b'408'])
                width = len(body)
                body = (body[:m.start()] + new + body[m.end():])
                body = body[:width].ljust(width)
                lines[i] = body + lines[i][len(body):]
    elif op == 3:
        if len(lines) > 2: lines.pop(rng.randrange(len(lines)))
    elif op == 4:
        i = rng.randrange(len(lines)); lines.insert(i, lines[i])
    elif op == 5:
        return d[:rng.randrange(len(d))]
    else:
        d = bytearray(d)
        for _ in range(rng.randrange(1, 4)):
            d[rng.randrange(len(d))] = rng.choice(b'0123456789,;.-E ')
        return bytes(d)
    return b'\n'.join(lines)


def make(i):
    rng = random.Random(seed * 1000003 + i)
    name, data = rng.choice(seeds)
    ext = os.path.splitext(name)[1]
    for _ in range(rng.randrange(1, 5)):
        if len(data) < 2: break
        data = (step_mutation if ext in ('.step', '.stp') else iges_mutation)(rng, data)
    path = os.path.join(outdir, 'case%06d%s' % (i, ext))
    with open(path, 'wb') as f: f.write(data)
    out = os.path.join(outdir, 'out%06d.json' % i)
    try:
        r = subprocess.run(['bash', '-c', 'ulimit -v 6000000; exec "$0" rods-from-cad "$1" --diameter 0.5 -o "$2"', rodfab, path, out],
                           capture_output=True, timeout=60)
        rc = r.returncode
        err = r.stderr[-300:]
    except subprocess.TimeoutExpired:
        rc, err = 'timeout', b''
    bad = rc not in (0, 1) or (rc == 1 and os.path.exists(out)) or (rc == 0 and not os.path.exists(out))
    if b'crashed on this file' in r.stderr if rc != 'timeout' else False:
        rc = 'contained-crash'
        bad = False
        os.rename(path, path + '.contained')
    elif not bad:
        os.remove(path)
    if os.path.exists(out): os.remove(out)
    return i, rc, bad, err


stats = {}
with cf.ThreadPoolExecutor(jobs) as ex:
    for i, rc, bad, err in ex.map(make, range(count)):
        stats[rc] = stats.get(rc, 0) + 1
        if bad:
            stats['bad'] = stats.get('bad', 0) + 1
            print('BAD', i, rc, err.decode(errors='replace').strip().replace('\n', ' | '), flush=True)
print('outcomes:', stats)
sys.exit(1 if 'bad' in stats else 0)
