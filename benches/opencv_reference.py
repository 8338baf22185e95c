#!/usr/bin/env python3
"""A plain OpenCV-Python pipeline of the default experiment's stages, for timing
probecal against (benches/compare-python.sh). It reads the same cached rendered
dataset probecal reads and does what a straightforward script would:

- camera calibration from the 16 views (findChessboardCorners on a half-size
  copy, cornerSubPix at full size, calibrateCamera);
- per photo, both 10x10 boards: findChessboardCorners on a half-size copy
  (adaptive threshold, without histogram equalisation, as probecal searches),
  cornerSubPix, the identification dots (one dot: probe board, two: phantom
  board, the dot beside the origin corner fixes the order), solvePnP;
- per B-scan, HoughCircles for the hemisphere's arc and a least-squares circle
  fit to the Canny edge points near it;
- Horn's closed form on the (arc centre, sphere centre in the marker frame)
  pairs and the thesis's cut-offs (drop the worst frame while its largest
  per-axis BRE is above the cut-off, refit);
- a pool of 2 processes over the frames.

It prints the frames used per cut-off and the calibration's error at the image
corners against the dataset's ground truth, so the timing is of a pipeline that
works. Usage: opencv_reference.py <rendered dataset folder>
"""

import csv
import json
import sys
from multiprocessing import Pool
from pathlib import Path

import cv2
import numpy as np

PROBE_BOARD = (10, 10)
SQUARE_MM = 13.0
CALIBRATION_BOARD = (9, 6)
CALIBRATION_SQUARE_MM = 30.0
SPACING_MM = 0.2
SPHERE_CENTRE_IN_PHANTOM_MM = np.array([285.7, 76.2, -26.5])
CUTOFFS_MM = [2.0, 1.5, 1.0]
CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.01)


def find_corners(grey, pattern):
    half = cv2.resize(grey, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
    found, corners = cv2.findChessboardCorners(half, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH)
    if not found:
        return None
    corners = corners * 2.0
    return cv2.cornerSubPix(grey, corners, (5, 5), (-1, -1), CRITERIA)


def board_points(pattern, square):
    cols, rows = pattern
    return np.array([[i * square, j * square, 0.0] for j in range(rows) for i in range(cols)], np.float32)


def calibrate(views_folder):
    object_points, image_points, size = [], [], None
    for path in sorted(Path(views_folder).glob("*.png")):
        grey = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        size = grey.shape[::-1]
        corners = find_corners(grey, CALIBRATION_BOARD)
        if corners is not None:
            object_points.append(board_points(CALIBRATION_BOARD, CALIBRATION_SQUARE_MM))
            image_points.append(corners)
    _, k, dist, _, _ = cv2.calibrateCamera(object_points, image_points, size, None, None)
    return k, dist


def orderings(cols, rows):
    """The grid's index maps for the four rotations (a square grid)."""
    grid = np.arange(cols * rows).reshape(rows, cols)
    return [np.rot90(grid, r).reshape(-1) for r in range(4)]


def disc_mean(grey, h, x_mm, y_mm, r_mm):
    ring = np.array([[x_mm + r_mm * dx, y_mm + r_mm * dy] for dx, dy in [(0, 0), (0.5, 0), (-0.5, 0), (0, 0.5), (0, -0.5)]], np.float32)
    px = cv2.perspectiveTransform(ring[None], h)[0]
    values = []
    for u, v in px:
        iu, iv = int(round(u)), int(round(v))
        if 0 <= iv < grey.shape[0] and 0 <= iu < grey.shape[1]:
            values.append(float(grey[iv, iu]))
    return np.mean(values) if len(values) == len(px) else None


def identify(grey, corners, pattern, square):
    """(dots, corners in board order) or None: the rotation with a dot beside its origin."""
    cols, rows = pattern
    plane = board_points(pattern, square)[:, :2]
    detected = corners.reshape(-1, 2)
    found = []
    for order in orderings(cols, rows):
        ordered = detected[order]
        h, _ = cv2.findHomography(plane, ordered)
        if h is None:
            continue
        s = square
        white = disc_mean(grey, h, -1.5 * s, 0.5 * s, 0.12 * s)
        black = disc_mean(grey, h, -0.5 * s, -0.5 * s, 0.12 * s)
        first = disc_mean(grey, h, -1.5 * s, -1.5 * s, 0.12 * s)
        second = disc_mean(grey, h, 1.0 * s, -1.5 * s, 0.12 * s)
        if None in (white, black, first, second) or white - black < 20:
            continue
        dark = lambda v: (white - v) / (white - black)
        if dark(first) > 0.5:
            found.append((2 if dark(second) > 0.5 else 1, ordered))
    return found[0] if len(found) == 1 else None


def pose(corners, k, dist):
    ok, rvec, tvec = cv2.solvePnP(board_points(PROBE_BOARD, SQUARE_MM), corners, k, dist)
    if not ok:
        return None
    m = np.eye(4)
    m[:3, :3] = cv2.Rodrigues(rvec)[0]
    m[:3, 3] = tvec.ravel()
    return m


def board_poses(photo, k, dist):
    grey = cv2.imread(str(photo), cv2.IMREAD_GRAYSCALE)
    poses = {}
    for _ in range(2):
        corners = find_corners(grey, PROBE_BOARD)
        if corners is None:
            break
        identified = identify(grey, corners, PROBE_BOARD, SQUARE_MM)
        hull = cv2.convexHull(corners.reshape(-1, 2).astype(np.int32))
        cv2.fillConvexPoly(grey, hull, 128)
        if identified is None:
            continue
        dots, ordered = identified
        p = pose(ordered.reshape(-1, 1, 2).astype(np.float32), k, dist)
        if p is not None:
            poses[dots] = p
    return poses


def arc_centre(bscan):
    """The hemisphere's arc: the bright ridges (above the 99th percentile of the
    blurred image), HoughCircles on them, and a least-squares circle through each
    column's brightest ridge pixel near the circle's upper half (the arc faces
    the probe)."""
    grey = cv2.imread(str(bscan), cv2.IMREAD_GRAYSCALE)
    blurred = cv2.GaussianBlur(grey, (7, 7), 2.0)
    ridge = (blurred > np.percentile(blurred, 99)).astype(np.uint8) * 255
    circles = cv2.HoughCircles(cv2.GaussianBlur(ridge, (5, 5), 1.5), cv2.HOUGH_GRADIENT, dp=1, minDist=400,
                               param1=100, param2=15, minRadius=30, maxRadius=80)
    if circles is None:
        return None
    cx, cy, r = circles[0][0]
    # Each column's brightest pixel on the arc's band.
    ys, xs = np.nonzero(ridge)
    near = (np.abs(np.hypot(xs - cx, ys - cy) - r) < 8) & (ys < cy)
    columns = {}
    for u, v in zip(xs[near], ys[near]):
        if u not in columns or blurred[v, u] > blurred[columns[u], u]:
            columns[u] = v
    if len(columns) < 20:
        return None
    x = np.array(list(columns.keys()), float)
    y = np.array(list(columns.values()), float)
    a = np.column_stack([x, y, np.ones_like(x)])
    c = np.linalg.lstsq(a, x * x + y * y, rcond=None)[0]
    return np.array([c[0] / 2, c[1] / 2])


def frame(args):
    folder, row, k, dist = args
    poses = board_poses(folder / row["camera_image"], k, dist)
    centre = arc_centre(folder / row["bscan_image"])
    if 1 not in poses or 2 not in poses or centre is None:
        return None
    camera_T_marker, camera_T_phantom = poses[1], poses[2]
    marker_T_phantom = np.linalg.inv(camera_T_marker) @ camera_T_phantom
    target = (marker_T_phantom @ np.append(SPHERE_CENTRE_IN_PHANTOM_MM, 1.0))[:3]
    return np.array([centre[0] * SPACING_MM, centre[1] * SPACING_MM, 0.0]), target, marker_T_phantom


def horn(x, y):
    mx, my = x.mean(0), y.mean(0)
    u, _, vt = np.linalg.svd((x - mx).T @ (y - my))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1, 1, d]) @ u.T
    return r, my - r @ mx


def bre(pairs, r, t):
    """Per frame, the largest per-axis back-projection error in the phantom frame, mm."""
    out = []
    for x, _, marker_T_phantom in pairs:
        in_marker = np.append(r @ x + t, 1.0)
        in_phantom = (np.linalg.inv(marker_T_phantom) @ in_marker)[:3]
        out.append(np.abs(in_phantom - SPHERE_CENTRE_IN_PHANTOM_MM).max())
    return np.array(out)


def main():
    folder = Path(sys.argv[1])
    k, dist = calibrate(folder / "camera_calibration")
    rows = list(csv.DictReader(open(folder / "frames.csv")))
    with Pool(2) as pool:
        results = pool.map(frame, [(folder, row, k, dist) for row in rows])
    pairs = [p for p in results if p is not None]
    r, t = horn(np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs]))
    for cutoff in CUTOFFS_MM:
        while True:
            errors = bre(pairs, r, t)
            worst = int(errors.argmax())
            if errors[worst] <= cutoff or len(pairs) <= 10:
                break
            pairs.pop(worst)
            r, t = horn(np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs]))
        print(f"cut-off {cutoff} mm: {len(pairs)} of {len(rows)} frames")
    truth = json.load(open(folder / "ground_truth.json"))
    marker_T_image = np.array(truth["marker_T_image"])
    w, h = truth["bscan_size_px"]
    corners = [(0, 0), (w - 1, 0), (0, h - 1), (w - 1, h - 1), ((w - 1) / 2, (h - 1) / 2)]
    error = np.mean([
        np.linalg.norm(r @ np.array([u * SPACING_MM, v * SPACING_MM, 0]) + t
                       - (marker_T_image @ np.array([u * SPACING_MM, v * SPACING_MM, 0, 1]))[:3])
        for u, v in corners
    ])
    print(f"{len(rows)} frames; image corners and centre {error:.3f} mm from the truth on average")


if __name__ == "__main__":
    main()
