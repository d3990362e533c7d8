#!/usr/bin/env python3
"""Writes kitchen_walk.csv: a walk with head sway through the BART kitchen, written for
testing methods on a path nobody tuned on. The eye walks from (1.5, 1.2, 2.8) to
(2.3, 1.2, 2.3) over 4 s with a 1.8 Hz bob of 3 cm, looks toward the counter with a yaw
sway of +-35 degrees at 0.6 Hz and a pitch of -20 degrees swaying +-6 at 0.4 Hz, 55 degree
field of view, keyed every 1/60 s over t = 0-4 s."""
import math, sys

rows = ["t,eye_x,eye_y,eye_z,at_x,at_y,at_z,up_x,up_y,up_z,fov_y_deg"]
for k in range(241):
    t = k / 60
    s = min(t / 4, 1.0)
    ex, ez = 1.5 + 0.8 * s, 2.8 - 0.5 * s
    ey = 1.2 + 0.03 * math.sin(2 * math.pi * 1.8 * t)
    a = math.atan2(2.39 - 1.5, 2.63 - 2.8) + math.radians(35) * math.sin(2 * math.pi * 0.6 * t)
    p = -0.35 + 0.1 * math.sin(2 * math.pi * 0.4 * t)
    at = (ex + math.sin(a) * math.cos(p), ey + math.sin(p), ez + math.cos(a) * math.cos(p))
    rows.append(f"{t:.6f},{ex:.6f},{ey:.6f},{ez:.6f},{at[0]:.6f},{at[1]:.6f},{at[2]:.6f},0,1,0,55")
open(sys.argv[1] if len(sys.argv) > 1 else "kitchen_walk.csv", "w").write("\n".join(rows) + "\n")
