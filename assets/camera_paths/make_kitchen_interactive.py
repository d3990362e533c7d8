#!/usr/bin/env python3
"""Writes kitchen_interactive.csv: a camera path written to mimic a person at the viewer.

Rows at 30 Hz (the rate a viewer recording would have), scene time 3.9-8.1 s (the
evaluation window 5-8 s plus its 1 s warm-up). A slow walk with drifting gaze, broken by
fast turns (85 deg in 0.25 s, like a mouse flick) and small hand jitter. Deterministic:
the jitter is a fixed sum of sines. Run from this folder: python3 make_kitchen_interactive.py
"""
import math

# (time s, yaw deg, pitch deg): yaw 0 looks along +x, 90 along +z. Between keys the gaze
# eases with a smoothstep, so short gaps are fast turns and long gaps slow drifts.
GAZE = [
    (3.9, -10, -25), (5.0, -20, -24),   # following the car, slow
    (5.25, 65, -12),                     # flick left: 85 deg in 0.25 s
    (5.9, 70, -10),                      # look around
    (6.3, -55, -22),                     # flick back right: 125 deg in 0.4 s
    (7.0, -30, -28),                     # slow pan
    (7.3, -125, -15),                    # fast turn: 95 deg in 0.3 s
    (8.1, -115, -18),
]
# (time s, eye x, y, z): a slow walk across the room.
WALK = [(3.9, 1.5, 1.2, 2.8), (6.0, 1.8, 1.22, 2.7), (8.1, 2.3, 1.2, 2.3)]


def smooth(a):
    return a * a * (3 - 2 * a)


def interp(keys, t):
    for (t0, *v0), (t1, *v1) in zip(keys, keys[1:]):
        if t0 <= t <= t1:
            a = smooth((t - t0) / (t1 - t0))
            return [x + (y - x) * a for x, y in zip(v0, v1)]
    return list(keys[-1][1:] if t > keys[-1][0] else keys[0][1:])


def main():
    with open("kitchen_interactive.csv", "w") as f:
        f.write("t,eye_x,eye_y,eye_z,at_x,at_y,at_z,up_x,up_y,up_z,fov_y_deg\n")
        n = int(round((8.1 - 3.9) * 30))
        for i in range(n + 1):
            t = 3.9 + i / 30
            yaw, pitch = interp(GAZE, t)
            yaw += 0.6 * math.sin(7.3 * t) + 0.3 * math.sin(17.1 * t + 1.0)
            pitch += 0.4 * math.sin(5.9 * t + 2.0) + 0.2 * math.sin(13.7 * t)
            ex, ey, ez = interp(WALK, t)
            ey += 0.01 * math.sin(2 * math.pi * 1.8 * t)  # steps
            y, p = math.radians(yaw), math.radians(pitch)
            d = (math.cos(p) * math.cos(y), math.sin(p), math.cos(p) * math.sin(y))
            f.write(
                f"{t:.4f},{ex:.5f},{ey:.5f},{ez:.5f},"
                f"{ex + d[0]:.5f},{ey + d[1]:.5f},{ez + d[2]:.5f},0,1,0,55\n"
            )


if __name__ == "__main__":
    main()
