#!/usr/bin/env python3
"""Writes docs/examples/arcade.gltf (+ arcade.bin), a second scene written to test the
methods on what nobody tuned them on (session 61, after the fence): a checkered floor,
two rows of columns at different depths (yellow and cyan in front, white behind), a
back wall of green and magenta bands of about equal luminance, a steel pendulum swinging
once every 1.2 s, a red box riding up and down, and a camera animated in the file: it
dollies in while turning a little left (0-1.5 s), holds (1.5-2.5 s), turns right fast,
like a head turn (2.5-3 s), holds (3-4 s), then rises and looks down (4-5 s).

    python3 docs/examples/make_arcade.py [OUTPUT_DIR]

Nothing but the standard library; boxes only (docs/examples/boxes.py).
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from boxes import about, cube_meshes, floats, material, node, out_dir, times, write  # noqa: E402

out = out_dir()

materials = [
    material("dark tile", [0.25, 0.25, 0.27], 0.0, 0.8),
    material("light tile", [0.6, 0.6, 0.58], 0.0, 0.8),
    material("green", [0.2, 0.55, 0.2], 0.0, 0.7),
    material("magenta", [0.8, 0.2, 0.8], 0.0, 0.7),
    material("yellow", [0.85, 0.75, 0.2], 0.0, 0.6),
    material("cyan", [0.2, 0.7, 0.75], 0.0, 0.6),
    material("white", [0.9, 0.9, 0.88], 0.0, 0.6),
    material("steel", [0.8, 0.8, 0.85], 1.0, 0.25),
    material("red", [0.8, 0.15, 0.12], 0.0, 0.5),
]
DARK, LIGHT, GREEN, MAGENTA, YELLOW, CYAN, WHITE, STEEL, RED = range(len(materials))
meshes = cube_meshes(materials)

for i in range(12):
    for k in range(12):
        node({"name": "tile %d %d" % (i, k), "mesh": DARK + (i + k) % 2,
              "translation": [-6 + i + 0.5, -0.05, -7 + k + 0.5], "scale": [1, 0.1, 1]})
for b in range(10):
    node({"name": "band %d" % b, "mesh": GREEN + b % 2,
          "translation": [0, 0.2 + 0.4 * b, -6.5], "scale": [12, 0.4, 0.2]})
for i in range(6):
    node({"name": "front column %d" % i, "mesh": YELLOW + i % 2,
          "translation": [-3.75 + 1.5 * i, 1.5, -2], "scale": [0.3, 3, 0.3]})
    node({"name": "back column %d" % i, "mesh": WHITE,
          "translation": [-3 + 1.5 * i, 1.5, -4.5], "scale": [0.3, 3, 0.3]})
rod = node({"name": "rod", "mesh": WHITE, "translation": [0, -0.9, 0],
            "scale": [0.04, 1.8, 0.04]}, root=False)
bob = node({"name": "bob", "mesh": STEEL, "translation": [0, -1.9, 0],
            "scale": [0.4, 0.4, 0.4]}, root=False)
pendulum = node({"name": "pendulum", "translation": [1.2, 3.2, -3.2], "children": [rod, bob]})
rider = node({"name": "rider", "mesh": RED, "translation": [-2.2, 0.5, -3.2],
              "scale": [0.6, 0.6, 0.6]})

# The camera's keys: time, position, yaw (left positive), pitch (down negative).
keys = [(0, [0, 1.6, 6], 0, -0.05), (0.75, [0.3, 1.6, 4], 0.15, -0.05),
        (1.5, [0.6, 1.6, 2], 0.3, -0.05), (2.5, [0.6, 1.6, 2], 0.3, -0.05),
        (3, [0.6, 1.6, 2], -0.5, -0.05), (4, [0.6, 1.6, 2], -0.5, -0.05),
        (5, [0.6, 2.6, 2], -0.5, -0.35), (6, [0.6, 2.6, 2], -0.5, -0.35)]
look = lambda yaw, pitch: times(about([0, 1, 0], yaw), about([1, 0, 0], pitch))
camera = node({"name": "camera", "camera": 0, "translation": keys[0][1],
               "rotation": look(keys[0][2], keys[0][3])})
lamp = node({"name": "lamp", "translation": [-1, 5, 0],
             "extensions": {"KHR_lights_punctual": {"light": 0}}})
sun = node({"name": "sun", "rotation": times(about([0, 1, 0], -0.6), about([1, 0, 0], -0.8)),
            "extensions": {"KHR_lights_punctual": {"light": 1}}})

# The pendulum: ±0.6 rad, a swing every 1.2 s, keyed every 0.1 s; the rider: 0.5 to 2.5 m
# and back every 2 s.
swing_t = [i / 10.0 for i in range(61)]
swing_q = sum((about([0, 0, 1], 0.6 * math.sin(2 * math.pi * t / 1.2)) for t in swing_t), [])
ride_t = [0.5 * i for i in range(13)]
ride = sum(([-2.2, 0.5 + 2.0 * (i % 2), -3.2] for i in range(13)), [])
cam_t = [k[0] for k in keys]
cam_at = sum((k[1] for k in keys), [])
cam_q = sum((look(k[2], k[3]) for k in keys), [])
cam_keys = floats(cam_t, "SCALAR")
samplers = [
    (floats(swing_t, "SCALAR"), floats(swing_q, "VEC4"), pendulum, "rotation"),
    (floats(ride_t, "SCALAR"), floats(ride, "VEC3"), rider, "translation"),
    (cam_keys, floats(cam_at, "VEC3"), camera, "translation"),
    (cam_keys, floats(cam_q, "VEC4"), camera, "rotation"),
]
lights = [
    {"name": "lamp", "type": "point", "color": [1, 0.95, 0.85], "intensity": 14},
    {"name": "sun", "type": "directional", "color": [0.85, 0.9, 1], "intensity": 1.2}]
write(out, "arcade", lights, 0.9, meshes, materials, samplers)
