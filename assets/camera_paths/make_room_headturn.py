#!/usr/bin/env python3
"""Writes room_headturn.csv: a head-turn path for the built-in `room`, written for
testing methods on a camera path nobody tuned on. The eye walks the room's clear ring
(radius 2.8 m, height 1.4 m) at 0.4 rad/s (about 1.1 m/s) and looks toward the centre
with a yaw sway of +-40 degrees at 0.5 Hz (peak about 126 deg/s), 60 degree field of
view, keyed every 1/60 s over t = 0-3 s."""
import math, sys

R, EYE_Y, AT_Y, SPEED, SWAY, SWAY_HZ = 2.8, 1.4, 1.3, 0.4, math.radians(40), 0.5
rows = ["t,eye_x,eye_y,eye_z,at_x,at_y,at_z,up_x,up_y,up_z,fov_y_deg"]
for k in range(181):
    t = k / 60
    th = SPEED * t
    ex, ez = R * math.sin(th), R * math.cos(th)
    # Toward the centre, turned by the sway.
    a = math.atan2(-math.sin(th), -math.cos(th)) + SWAY * math.sin(2 * math.pi * SWAY_HZ * t)
    rows.append(f"{t:.6f},{ex:.6f},{EYE_Y:.6f},{ez:.6f},{ex + math.sin(a):.6f},{AT_Y:.6f},{ez + math.cos(a):.6f},0,1,0,60")
open(sys.argv[1] if len(sys.argv) > 1 else "room_headturn.csv", "w").write("\n".join(rows) + "\n")
