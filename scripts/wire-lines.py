#!/usr/bin/python3
"""Do fCal 2.0's wire dots say where ImageToProbe's turns are?

A second objective for docs/guide/selfcal.md, measured with numpy as a plain
reference: the phantom's geometry is not used, only that each of its nine wires
is a straight line. The dots probecal segmented and labelled in both sweeps
(reports/plus_fcal2_nwire/fcal2_3nwires/frames.csv, used frames) are placed in
the Reference frame with the sequences' poses at image time + the run's lag
(rotations interpolated on SO(3), translations linearly, between the two
frames that bracket that time), and a correction of ImageToProbe (a turn about
the image's centre and a move, in the probe's frame) is sought that puts each
wire's dots, from whichever sweep, closest to one straight line (Gauss-Newton
on the dots' distances to each wire's best-fitting line).

Writes <reports>/selfcal/wire_lines.json: the turn found from PLUS's matrix and from probecal's on each sweep
alone and on both (with its standard deviation from the residuals), and how far
the image's corners end from PLUS's matrix from starts turned 2 degrees about
each axis. Usage: scripts/wire-lines.py [reports]
"""
import csv
import json
import os
import re
import sys

import numpy as np

REPORTS = sys.argv[1] if len(sys.argv) > 1 else "reports"
# The run scripts/selfcal.sh refines from: the committed one.
RUN = os.path.join("reports", "plus_fcal2_nwire", "fcal2_3nwires")
DATA = os.path.join("..", "shared", "data", "plus-fcal2.0-3nwires")
SEQUENCES = {
    "calibration": "fCal_Test_Calibration_3NWires_fCal2.0.igs.mha",
    "validation": "fCal_Test_Validation_3NWires_fCal2.0.igs.mha",
}
HEADER_LIMIT_BYTES = 1 << 20
TURN_DEG = 2.0
ITERATIONS = 30


def read_header(path):
    """The sequence's header: per frame, both transforms and the timestamp."""
    with open(path, "rb") as f:
        text = f.read(HEADER_LIMIT_BYTES).split(b"ElementDataFile")[0].decode("latin-1")
    size = [int(v) for v in re.search(r"DimSize = ([\d ]+)", text).group(1).split()]
    frames = {}
    pattern = r"Seq_Frame(\d+)_(ProbeToTrackerTransform|ReferenceToTrackerTransform|Timestamp) = ([^\n]+)"
    for m in re.finditer(pattern, text):
        frame = frames.setdefault(int(m.group(1)), {})
        if m.group(2) == "Timestamp":
            frame["t"] = float(m.group(3))
        else:
            frame[m.group(2)] = np.array([float(v) for v in m.group(3).split()]).reshape(4, 4)
    return size, frames


def log_so3(r):
    angle = np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1))
    if angle < 1e-12:
        return np.zeros(3)
    w = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    return w * angle / (2 * np.sin(angle))


def exp_so3(w):
    angle = np.linalg.norm(w)
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    if angle < 1e-12:
        return np.eye(3) + k
    return np.eye(3) + np.sin(angle) / angle * k + (1 - np.cos(angle)) / angle**2 * k @ k


def pose_at(frames, key, t):
    """The transform at time t between the two frames that bracket it."""
    times = sorted((f["t"], i) for i, f in frames.items())
    for (t0, i0), (t1, i1) in zip(times, times[1:]):
        if t0 <= t <= t1:
            a, b = frames[i0][key], frames[i1][key]
            s = (t - t0) / (t1 - t0)
            out = np.eye(4)
            out[:3, :3] = a[:3, :3] @ exp_so3(s * log_so3(a[:3, :3].T @ b[:3, :3]))
            out[:3, 3] = (1 - s) * a[:3, 3] + s * b[:3, 3]
            return out
    return None


def dots(lag_s):
    """Each used frame's labelled dots: (sweep, wire, reference_T_probe, pixel)."""
    headers = {name: read_header(os.path.join(DATA, f)) for name, f in SEQUENCES.items()}
    out = []
    with open(os.path.join(RUN, "frames.csv")) as f:
        for row in csv.DictReader(f):
            if row["status"] != "used":
                continue
            frames = headers[row["sequence"]][1]
            t = frames[int(row["frame"])]["t"] + lag_s
            probe = pose_at(frames, "ProbeToTrackerTransform", t)
            reference = pose_at(frames, "ReferenceToTrackerTransform", t)
            if probe is None or reference is None:
                continue
            reference_t_probe = np.linalg.inv(reference) @ probe
            for n in range(3):
                for w in range(3):
                    u, v = row[f"n{n + 1}_wire{w + 1}_u_px"], row[f"n{n + 1}_wire{w + 1}_v_px"]
                    if u and v:
                        out.append((row["sequence"], 3 * n + w, reference_t_probe, [float(u), float(v), 0.0, 1.0]))
    return headers["calibration"][0], out


class Lines:
    def __init__(self, observations, size):
        self.wire = np.array([o[1] for o in observations])
        self.chain = np.stack([o[2] for o in observations])
        self.pixel = np.array([o[3] for o in observations])
        self.centre = np.array([(size[0] - 1) / 2, (size[1] - 1) / 2, 0.0, 1.0])

    def corrected(self, image_to_probe, p):
        """ImageToProbe turned by p[:3] (radians) about the image's centre, moved by p[3:] (mm)."""
        c = (image_to_probe @ self.centre)[:3]
        g = np.eye(4)
        g[:3, :3] = exp_so3(p[:3])
        g[:3, 3] = c - g[:3, :3] @ c + p[3:]
        return g @ image_to_probe

    def residuals(self, image_to_probe):
        points = np.einsum("nij,jk,nk->ni", self.chain, image_to_probe, self.pixel)[:, :3]
        out = []
        for w in np.unique(self.wire):
            q = points[self.wire == w]
            q = q - q.mean(axis=0)
            direction = np.linalg.svd(q, full_matrices=False)[2][0]
            out.append(q - np.outer(q @ direction, direction))
        return np.concatenate(out).ravel()

    def jacobian(self, image_to_probe, p, free):
        r = self.residuals(self.corrected(image_to_probe, p))
        j = np.zeros((r.size, len(free)))
        for k, i in enumerate(free):
            step = 1e-6 if i < 3 else 1e-4
            q = p.copy()
            q[i] += step
            j[:, k] = (self.residuals(self.corrected(image_to_probe, q)) - r) / step
        return r, j

    def refine(self, image_to_probe, free):
        p = np.zeros(6)
        for _ in range(ITERATIONS):
            r, j = self.jacobian(image_to_probe, p, free)
            step = np.linalg.lstsq(j, -r, rcond=None)[0]
            p[free] += step
            if np.max(np.abs(step)) < 1e-10:
                break
        r, j = self.jacobian(image_to_probe, p, free)
        # Three residual components per dot, two of them free: the dots' degrees of freedom.
        dof = 2 * self.wire.size - 4 * len(np.unique(self.wire)) - len(free)
        sigma2 = r @ r / dof
        sd = np.sqrt(np.diag(np.linalg.inv(j.T @ j)) * sigma2)
        return p, sd, float(np.sqrt(sigma2 / 2))


def corner_distance_mm(a, b, size):
    corners = np.array([[0, 0, 0, 1], [size[0] - 1, 0, 0, 1], [0, size[1] - 1, 0, 1], [size[0] - 1, size[1] - 1, 0, 1]], float).T
    return float(np.max(np.linalg.norm((a @ corners - b @ corners)[:3], axis=0)))


def main():
    with open(os.path.join(RUN, "summary.json")) as f:
        summary = json.load(f)
    lag_s = summary["time_offset_s"]
    plus = np.array(summary["plus_result"]["matrix"])
    ours = np.array(summary["image_to_probe"]["matrix"])
    size, observations = dots(lag_s)
    result = {"lag_s": round(lag_s, 6), "dots": len(observations), "turn_deg_about": ["x", "y", "z"]}
    everything = Lines(observations, size)
    sweeps = {}
    for name, keep in (("both", lambda o: True), ("calibration", lambda o: o[0] == "calibration"), ("validation", lambda o: o[0] == "validation")):
        lines = Lines([o for o in observations if keep(o)], size)
        for start_name, start in (("plus", plus), ("probecal", ours)):
            p, sd, rms = lines.refine(start, [0, 1, 2])
            sweeps.setdefault(name, {})[start_name] = {
                "dots": int(lines.wire.size),
                "turn_deg": [round(float(np.degrees(v)), 2) for v in p[:3]],
                "turn_sd_deg": [round(float(np.degrees(v)), 2) for v in sd],
                "corner_change_mm": round(corner_distance_mm(lines.corrected(start, p), start, size), 2),
                "corners_from_plus_mm": round(corner_distance_mm(lines.corrected(start, p), plus, size), 2),
                "rms_mm": round(rms, 3),
            }
    result["turn_only"] = sweeps
    turned = []
    for axis in range(3):
        for sign in (1, -1):
            p0 = np.zeros(6)
            p0[axis] = sign * np.radians(TURN_DEG)
            start = everything.corrected(plus, p0)
            p, _, _ = everything.refine(start, [0, 1, 2])
            turned.append({
                "axis": "xyz"[axis],
                "turn_deg": sign * TURN_DEG,
                "start_from_plus_mm": round(corner_distance_mm(start, plus, size), 2),
                "after_from_plus_mm": round(corner_distance_mm(everything.corrected(start, p), plus, size), 2),
            })
    result["turned_starts"] = turned
    result["turned_starts_median_mm"] = {
        "start": round(float(np.median([t["start_from_plus_mm"] for t in turned])), 2),
        "after": round(float(np.median([t["after_from_plus_mm"] for t in turned])), 2),
    }
    out = os.path.join(REPORTS, "selfcal", "wire_lines.json")
    os.makedirs(os.path.dirname(out), exist_ok=True)
    with open(out + ".tmp", "w") as f:
        json.dump(result, f, indent=1)
        f.write("\n")
    os.replace(out + ".tmp", out)
    print(f"wire lines: {out}")


if __name__ == "__main__":
    main()
