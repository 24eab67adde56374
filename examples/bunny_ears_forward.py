#!/usr/bin/env python3
"""Adds a training case to a bunny design made by `rodfab rods-from-mesh`: the rod nodes within 3 mm of
the lowest one are clamped to the tray, and the two highest nodes (the ear tips) are pulled forward
(towards -y, where the bunny looks) by FORCE newtons each.

    python3 examples/bunny_ears_forward.py BUNNY.json TRAINED.json [FORCE]
"""
import json
import sys

design_file, output = sys.argv[1], sys.argv[2]
force = float(sys.argv[3]) if len(sys.argv) > 3 else 0.001
design = json.load(open(design_file))
# Rod ends are the nodes: rods-from-mesh ends every rod meeting at a node on exactly the same point.
nodes = sorted({tuple(r["centerline"]["points"][i]) for r in design["rods"] for i in (0, -1)})
lowest = min(p[2] for p in nodes)
base = [p for p in nodes if p[2] < lowest + 3.0]
tips = sorted(nodes, key=lambda p: -p[2])[:2]
design["mechanics"] = {
    "joints": "auto",
    "load_steps": 4,
    "supports": [{"at": {"point": list(p)}, "type": "clamped"} for p in base],
    "loads": [{"at": {"point": list(p)}, "force": [0.0, -force, 0.0]} for p in tips],
}
json.dump(design, open(output, "w"), indent=1)
print(f"{len(base)} clamped nodes at the base, ear tips {tips[0]} and {tips[1]} pulled by {force} N towards -y")
