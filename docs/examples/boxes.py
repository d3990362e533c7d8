"""Helpers of the example scene writers (make_fence.py, make_arcade.py): a glTF 2.0
document of boxes, every mesh a scaled unit cube, its buffer written beside it.
Nothing but the standard library."""
import json
import math
import os
import struct
import sys

data = bytearray()
views, accessors = [], []


def view(b):
    while len(data) % 4:
        data.append(0)
    views.append({"buffer": 0, "byteOffset": len(data), "byteLength": len(b)})
    data.extend(b)
    return len(views) - 1


def floats(vals, ty):
    comps = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[ty]
    a = {"bufferView": view(struct.pack("<%df" % len(vals), *vals)),
         "componentType": 5126, "count": len(vals) // comps, "type": ty}
    if ty in ("VEC3", "SCALAR"):  # the specification asks bounds of positions and key times
        a["min"] = [min(vals[k::comps]) for k in range(comps)]
        a["max"] = [max(vals[k::comps]) for k in range(comps)]
    accessors.append(a)
    return len(accessors) - 1


def indices(vals):
    accessors.append({"bufferView": view(struct.pack("<%dH" % len(vals), *vals)),
                      "componentType": 5123, "count": len(vals), "type": "SCALAR"})
    return len(accessors) - 1


def unit_cube(material):
    pos, nor, idx = [], [], []
    for axis in range(3):
        for side in (-1, 1):
            n = [0, 0, 0]
            n[axis] = side
            u, w, base = (axis + 1) % 3, (axis + 2) % 3, len(pos) // 3
            for a, c in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = [0.0, 0.0, 0.0]
                p[axis], p[u], p[w] = side * 0.5, a * 0.5, c * 0.5
                pos += p
                nor += n
            # Counter-clockwise seen from outside.
            idx += [base, base + 1, base + 2, base, base + 2, base + 3] if side > 0 \
                else [base, base + 2, base + 1, base, base + 3, base + 2]
    return {"attributes": {"POSITION": floats(pos, "VEC3"), "NORMAL": floats(nor, "VEC3")},
            "indices": indices(idx), "material": material}


def about(axis, angle):
    s = math.sin(angle / 2)
    return [axis[0] * s, axis[1] * s, axis[2] * s, math.cos(angle / 2)]


def times(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return [aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz]


def material(name, rgb, metallic, roughness):
    return {"name": name, "pbrMetallicRoughness": {
        "baseColorFactor": rgb + [1.0], "metallicFactor": metallic, "roughnessFactor": roughness}}


nodes, roots = [], []


def node(d, root=True):
    nodes.append(d)
    if root:
        roots.append(len(nodes) - 1)
    return len(nodes) - 1



def out_dir():
    """The folder a writer writes to: its first argument, else the scripts' own."""
    return sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__))


def cube_meshes(materials):
    """One unit-cube mesh per material, named as it, in the materials' order."""
    return [{"name": m["name"], "primitives": [unit_cube(i)]} for i, m in enumerate(materials)]


def write(out, name, lights, yfov, meshes, materials, samplers):
    """Write the scene as OUT/NAME.gltf with its buffer as OUT/NAME.bin: the nodes made
    so far, `lights` (KHR_lights_punctual), one perspective camera of vertical field of
    view `yfov`, and one animation of `samplers`, each `(input accessor, output
    accessor, node, path)`, linearly interpolated."""
    while len(data) % 4:
        data.append(0)
    doc = {
        "asset": {"version": "2.0", "generator": "frameless docs/examples/make_%s.py" % name},
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": lights}},
        "scene": 0,
        "scenes": [{"name": name, "nodes": roots}],
        "nodes": nodes,
        "cameras": [{"type": "perspective",
                     "perspective": {"yfov": yfov, "znear": 0.05, "aspectRatio": 1.0}}],
        "meshes": meshes,
        "materials": materials,
        "animations": [{"name": name, "channels": [
            {"sampler": i, "target": {"node": n, "path": p}}
            for i, (_, _, n, p) in enumerate(samplers)],
            "samplers": [{"input": a, "output": o, "interpolation": "LINEAR"}
                         for a, o, _, _ in samplers]}],
        "bufferViews": views,
        "accessors": accessors,
        "buffers": [{"byteLength": len(data), "uri": name + ".bin"}],
    }
    with open(os.path.join(out, name + ".gltf"), "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    with open(os.path.join(out, name + ".bin"), "wb") as f:
        f.write(data)
    print("wrote %s and %s.bin (%d bytes)" % (os.path.join(out, name + ".gltf"), name, len(data)))
