#!/usr/bin/env python3
"""Writes gltf_demo_walk.csv: a walk with head sway for docs/examples/demo.gltf, written
for testing methods on a glTF scene and path nobody tuned on. The eye descends from the
file's own camera (0, 3.4, 8) to (2.5, 1.6, 5) over 3 s with a 1.9 Hz bob of 2 cm,
looks toward the scene's centre with a yaw sway of +-30 degrees at 0.7 Hz and a pitch
rising from -18.6 to -10.6 degrees, 43 degree field of view (the file's), keyed every
1/60 s over t = 0-3 s."""
import math, sys

rows = ["t,eye_x,eye_y,eye_z,at_x,at_y,at_z,up_x,up_y,up_z,fov_y_deg"]
for k in range(181):
    t = k / 60
    s = min(t / 3, 1.0)
    ex, ez = 2.5 * s, 8.0 - 3.0 * s
    ey = 3.4 - 1.8 * s + 0.02 * math.sin(2 * math.pi * 1.9 * t)
    yaw = math.atan2(-ex, -ez) + math.radians(30) * math.sin(2 * math.pi * 0.7 * t)
    pitch = math.radians(-18.6 + 8 * s)
    d = (math.sin(yaw) * math.cos(pitch), math.sin(pitch), math.cos(yaw) * math.cos(pitch))
    rows.append(f"{t:.6f},{ex:.6f},{ey:.6f},{ez:.6f},{ex + d[0]:.6f},{ey + d[1]:.6f},{ez + d[2]:.6f},0,1,0,43")
open(sys.argv[1] if len(sys.argv) > 1 else "gltf_demo_walk.csv", "w").write("\n".join(rows) + "\n")
