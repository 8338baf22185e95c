#!/usr/bin/env python3
"""The hand's speed during a freehand calibration sweep, measured from a PLUS
sequence's ProbeToTracker poses: RMS speed of the probe marker's origin (mm/s)
and RMS angular speed (deg/s), over spans of 6 frames (about 0.5 s, so the
tracker's jitter does not count as motion).

    python3 scripts/hand-speed.py ../shared/data/plus-fcal2.0-3nwires/fCal_Test_Calibration_3NWires_fCal2.0.igs.mha

The twin experiments (experiments/thesis_twin_*.yaml) quote its output as
`realism.hand`; tests/thesis_twin.rs checks that they agree.
"""
import math
import re
import sys

SPAN = 6


def header(path):
    text = b""
    with open(path, "rb") as f:
        for line in f:
            text += line
            if line.startswith(b"ElementDataFile"):
                break
    return text.decode("latin1")


def poses(path):
    frames = {}
    for m in re.finditer(r"Seq_Frame(\d+)_(\w+?) = (.*)", header(path)):
        frames.setdefault(int(m.group(1)), {})[m.group(2)] = m.group(3).strip()
    out = []
    for k in sorted(frames):
        d = frames[k]
        if d.get("ProbeToTrackerTransformStatus", "OK") != "OK" or "ProbeToTrackerTransform" not in d:
            continue
        m = [float(x) for x in d["ProbeToTrackerTransform"].split()]
        out.append((float(d["Timestamp"]), [m[0:3], m[4:7], m[8:11]], [m[3], m[7], m[11]]))
    return out


def angle_deg(a, b):
    trace = sum(a[i][j] * b[i][j] for i in range(3) for j in range(3))
    return math.degrees(math.acos(max(-1.0, min(1.0, (trace - 1.0) / 2.0))))


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: hand-speed.py <PLUS sequence .mha>")
    p = poses(sys.argv[1])
    if len(p) <= SPAN:
        sys.exit(f"{sys.argv[1]}: fewer than {SPAN + 1} tracked frames")
    speeds, spins = [], []
    for (t0, r0, x0), (t1, r1, x1) in zip(p[:-SPAN], p[SPAN:]):
        dt = t1 - t0
        if dt <= 0:
            continue
        speeds.append(math.dist(x0, x1) / dt)
        spins.append(angle_deg(r0, r1) / dt)
    rms = lambda v: math.sqrt(sum(x * x for x in v) / len(v))
    print(f"frames {len(p)} spans {len(speeds)}")
    print(f"speed_mm_per_s {rms(speeds):.2f}")
    print(f"rotation_deg_per_s {rms(spins):.2f}")


if __name__ == "__main__":
    main()
