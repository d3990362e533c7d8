#!/usr/bin/env python3
"""Writes docs/examples/fence.gltf (+ fence.bin), a scene written to test the methods on
what nobody tuned them on: a picket fence of thin white boards before a wall of narrow
red and blue stripes (edges in front of edges, at another depth), a windmill whose four
blades turn one and a half times a second, a steel cube sliding to and fro, and a camera
animated in the file itself: it strafes right past the fence (0-2 s), slows and stops
(2-2.5 s), holds (2.5-3.5 s), pans 40 degrees (3.5-4.5 s) and holds again.

    python3 docs/examples/make_fence.py [OUTPUT_DIR]

Nothing but the standard library; boxes only, so every node is a scaled unit cube.
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from boxes import about, cube_meshes, floats, material, node, out_dir, times, write  # noqa: E402

out = out_dir()
materials = [
    material("grass", [0.35, 0.5, 0.25], 0.0, 0.9),
    material("white", [0.92, 0.9, 0.85], 0.0, 0.6),
    material("red", [0.75, 0.2, 0.15], 0.0, 0.7),
    material("blue", [0.15, 0.3, 0.7], 0.0, 0.7),
    material("steel", [0.8, 0.8, 0.85], 1.0, 0.2),
    material("wood", [0.55, 0.4, 0.25], 0.0, 0.8),
]
GRASS, WHITE, RED, BLUE, STEEL, WOOD = range(len(materials))
meshes = cube_meshes(materials)
node({"name": "ground", "mesh": GRASS, "translation": [0, -0.05, 0], "scale": [30, 0.1, 30]})
for i in range(31):
    node({"name": "picket %d" % i, "mesh": WHITE, "translation": [-7.5 + i * 0.5, 0.6, -1.0],
          "scale": [0.09, 1.2, 0.05]})
for y in (0.3, 0.95):
    node({"name": "rail", "mesh": WHITE, "translation": [0, y, -1.04], "scale": [15.5, 0.08, 0.03]})
for i in range(40):
    node({"name": "stripe %d" % i, "mesh": RED + i % 2, "translation": [-9.75 + i * 0.5, 1.5, -4.0],
          "scale": [0.5, 3.0, 0.2]})
node({"name": "tower", "mesh": WOOD, "translation": [1.6, 1.3, -2.6], "scale": [0.25, 2.6, 0.25]})
blades = []
for k in range(4):
    shape = node({"name": "blade %d shape" % k, "mesh": WHITE, "translation": [0.7, 0, 0],
                  "scale": [1.3, 0.18, 0.04]}, root=False)
    blades.append(node({"name": "blade %d" % k, "rotation": about([0, 0, 1], k * math.pi / 2),
                        "children": [shape]}, root=False))
hub = node({"name": "hub", "translation": [1.6, 2.6, -2.4], "children": blades})
slider = node({"name": "slider", "mesh": STEEL, "translation": [-2.5, 0.35, 0.2],
               "scale": [0.7, 0.7, 0.7]})

# The camera's keys: time, x, yaw (height 1.2, 3.2 in front of the fence, pitched down a little).
keys = [(0, -4, 0.15), (0.5, -2.5, 0.12), (1, -1, 0.09), (1.5, 0.5, 0.06), (2, 2, 0.03),
        (2.25, 2.4, 0.01), (2.5, 2.5, 0), (3.5, 2.5, 0), (4.5, 2.5, 0.7), (6, 2.5, 0.7)]
look = lambda yaw: times(about([0, 1, 0], yaw), about([1, 0, 0], -0.04))
camera = node({"name": "camera", "camera": 0, "translation": [keys[0][1], 1.2, 3.2],
               "rotation": look(keys[0][2])})
lamp = node({"name": "lamp", "translation": [-2, 4, 3], "extensions": {"KHR_lights_punctual": {"light": 0}}})
sun = node({"name": "sun", "rotation": times(about([0, 1, 0], 0.5), about([1, 0, 0], -0.9)),
            "extensions": {"KHR_lights_punctual": {"light": 1}}})

# Keys a quarter turn apart (slerp takes the short way), six a second: 1.5 turns a second.
spin_t = [i / 6.0 for i in range(37)]
spin_q = sum((about([0, 0, 1], -i * math.pi / 2) for i in range(37)), [])
slide_t = list(range(7))
slide = sum(([-2.5 + 5.0 * (i % 2), 0.35, 0.2] for i in range(7)), [])
cam_t = [k[0] for k in keys]
cam_at = sum(([k[1], 1.2, 3.2] for k in keys), [])
cam_q = sum((look(k[2]) for k in keys), [])
cam_keys = floats(cam_t, "SCALAR")
samplers = [
    (floats(spin_t, "SCALAR"), floats(spin_q, "VEC4"), hub, "rotation"),
    (floats(slide_t, "SCALAR"), floats(slide, "VEC3"), slider, "translation"),
    (cam_keys, floats(cam_at, "VEC3"), camera, "translation"),
    (cam_keys, floats(cam_q, "VEC4"), camera, "rotation"),
]
lights = [
    {"name": "lamp", "type": "point", "color": [1, 0.95, 0.85], "intensity": 60},
    {"name": "sun", "type": "directional", "color": [0.8, 0.85, 1], "intensity": 0.5}]
write(out, "fence", lights, 0.8, meshes, materials, samplers)
