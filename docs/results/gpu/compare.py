#!/usr/bin/env python3
"""Per-frame RMS difference (0-255) between two folders of PNG frames written by
`frameless render` (the same run with `--recon cpu` and `--recon gpu`).

Usage: python3 compare.py CPU_DIR GPU_DIR
Prints one line per frame and a summary (largest and mean RMS difference). Standard
library only (a minimal decoder of 8-bit, non-interlaced RGB/RGBA PNG).
"""
import math
import struct
import sys
import zlib
from pathlib import Path


def read_png(path):
    data = path.read_bytes()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise SystemExit(f"{path}: not a PNG file")
    pos, idat, width, height, channels = 8, b"", 0, 0, 0
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if depth != 8 or interlace != 0 or colour not in (2, 6):
                raise SystemExit(f"{path}: only 8-bit non-interlaced RGB/RGBA PNG is read")
            channels = 3 if colour == 2 else 4
        elif kind == b"IDAT":
            idat += body
    raw = zlib.decompress(idat)
    stride = width * channels
    out = bytearray(height * stride)
    prev = bytearray(stride)
    for y in range(height):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - channels] if i >= channels else 0
            b = prev[i]
            c = prev[i - channels] if i >= channels else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[i] = (line[i] + pred) & 255
        out[y * stride:(y + 1) * stride] = line
        prev = line
    rgb = [v for i, v in enumerate(out) if channels == 3 or i % 4 != 3]
    return width, height, rgb


def main():
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    a_dir, b_dir = Path(sys.argv[1]), Path(sys.argv[2])
    frames = sorted(p.name for p in a_dir.glob("*.png"))
    if not frames:
        raise SystemExit(f"{a_dir}: no PNG frames")
    worst, total = 0.0, 0.0
    for name in frames:
        if not (b_dir / name).exists():
            raise SystemExit(f"{b_dir / name}: missing (the other folder has it)")
        wa, ha, a = read_png(a_dir / name)
        wb, hb, b = read_png(b_dir / name)
        if (wa, ha) != (wb, hb):
            raise SystemExit(f"{name}: {wa}x{ha} against {wb}x{hb}")
        rms = math.sqrt(sum((x - y) ** 2 for x, y in zip(a, b)) / len(a))
        worst, total = max(worst, rms), total + rms
        print(f"{name} {rms:.4f}")
    print(f"frames {len(frames)}: largest RMS difference {worst:.4f}, mean {total / len(frames):.4f} (0-255)")


if __name__ == "__main__":
    main()
