#!/usr/bin/python3
"""OpenCV-Python's ChArUco results (python3-opencv 4.6, Debian), the reference
probecal's ChArUco detection and camera calibration are compared with.

    opencv_reference.py detect IMAGE BOARD          -> JSON markers and corners
    opencv_reference.py calibrate FOLDER BOARD      -> JSON calibrateCameraCharuco
    opencv_reference.py render FOLDER BOARD VIEWS SEED -> ChArUco photos

BOARD is `SXxSY:SQUARE:MARKER:DICTIONARY` (a dictionary name or file). `render`
draws the board with OpenCV's own `CharucoBoard.draw` and photographs it with a
pinhole camera with radial distortion (K and distortion below) from random
poses, with a 0.7 px blur and sensor noise of 2 grey levels: photos made
without probecal.
"""
import glob
import json
import os
import sys

import cv2
import numpy as np

MIN_VIEW_CORNERS = 6
CAMERA = np.array([[820.0, 0.0, 331.0], [0.0, 815.0, 243.0], [0.0, 0.0, 1.0]])
DISTORTION = np.array([-0.21, 0.11, 0.0, 0.0, 0.0])
SIZE = (640, 480)


def board(text):
    squares, square, marker, name = text.split(":")
    sx, sy = [int(v) for v in squares.split("x")]
    if name.startswith("DICT_"):
        dictionary = cv2.aruco.Dictionary_get(getattr(cv2.aruco, name))
    else:
        dictionary = cv2.aruco.Dictionary_get(cv2.aruco.DICT_4X4_50)
        fs = cv2.FileStorage(name, cv2.FILE_STORAGE_READ)
        assert dictionary.readDictionary(fs.root()), name
    return dictionary, cv2.aruco.CharucoBoard_create(sx, sy, float(square), float(marker), dictionary)


def detect(image, dictionary, charuco):
    corners, ids, _ = cv2.aruco.detectMarkers(image, dictionary)
    marker_ids = [] if ids is None else sorted(int(i) for i in ids.ravel())
    if ids is None:
        return marker_ids, [], []
    n, points, point_ids = cv2.aruco.interpolateCornersCharuco(corners, ids, image, charuco)
    if not n:
        return marker_ids, [], []
    pairs = sorted(zip(point_ids.ravel().tolist(), points.reshape(-1, 2).tolist()))
    return marker_ids, [p[0] for p in pairs], [p[1] for p in pairs]


def images(folder):
    return sorted(f for f in glob.glob(os.path.join(folder, "*")) if f.lower().endswith((".png", ".jpg")))


def calibrate(folder, dictionary, charuco):
    all_corners, all_ids, used, size = [], [], [], None
    for path in images(folder):
        image = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        size = (image.shape[1], image.shape[0])
        _, ids, points = detect(image, dictionary, charuco)
        if len(ids) < MIN_VIEW_CORNERS:
            continue
        all_corners.append(np.array(points, dtype=np.float32).reshape(-1, 1, 2))
        all_ids.append(np.array(ids, dtype=np.int32).reshape(-1, 1))
        used.append(os.path.basename(path))
    rms, k, d, _, _ = cv2.aruco.calibrateCameraCharuco(all_corners, all_ids, charuco, size, None, None)
    return {"rms": rms, "camera_matrix": k.tolist(), "distortion": d.ravel().tolist(), "used": used}


def render(folder, charuco, views, seed):
    rng = np.random.default_rng(seed)
    sx, sy = charuco.getChessboardSize()
    width, height = int(sx * 12 * 10), int(sy * 12 * 10)
    flat = charuco.draw((width, height), marginSize=0, borderBits=1)
    scale = width / (sx * charuco.getSquareLength())
    grid = np.stack(np.meshgrid(np.arange(SIZE[0]), np.arange(SIZE[1])), -1).reshape(-1, 1, 2).astype(np.float64)
    rays = cv2.undistortPoints(grid, CAMERA, DISTORTION).reshape(-1, 2)
    os.makedirs(folder, exist_ok=True)
    centre = np.array([sx, sy, 0.0]) * charuco.getSquareLength() / 2
    for v in range(views):
        angles = rng.uniform(-0.6, 0.6, 3) * np.array([1, 1, 0.5])
        rotation, _ = cv2.Rodrigues(angles)
        distance = rng.uniform(3.2, 4.2) * sx * charuco.getSquareLength()
        shift = rng.uniform(-0.12, 0.12, 2) * distance
        translation = np.array([shift[0], shift[1], distance]) - rotation @ centre
        # Each pixel's ray meets the board plane z = 0 (board frame).
        normal = rotation[:, 2]
        t_along = (normal @ translation) / (rays @ normal[:2] + normal[2])
        points_cam = np.column_stack([rays * t_along[:, None], t_along])
        board_xy = (points_cam - translation) @ rotation
        map_x = (board_xy[:, 0] * scale).reshape(SIZE[1], SIZE[0]).astype(np.float32)
        map_y = (board_xy[:, 1] * scale).reshape(SIZE[1], SIZE[0]).astype(np.float32)
        photo = cv2.remap(flat, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=200)
        photo = cv2.GaussianBlur(photo.astype(np.float64), (0, 0), 0.7)
        photo = np.clip(photo + rng.normal(0, 2.0, photo.shape), 0, 255).round().astype(np.uint8)
        cv2.imwrite(os.path.join(folder, f"view_{v:02d}.png"), photo)


def main():
    command, target, spec = sys.argv[1], sys.argv[2], sys.argv[3]
    dictionary, charuco = board(spec)
    if command == "detect":
        image = cv2.imread(target, cv2.IMREAD_GRAYSCALE)
        marker_ids, ids, points = detect(image, dictionary, charuco)
        print(json.dumps({"marker_ids": marker_ids, "corner_ids": ids, "corners": points}))
    elif command == "calibrate":
        print(json.dumps(calibrate(target, dictionary, charuco)))
    elif command == "render":
        render(target, charuco, int(sys.argv[4]), int(sys.argv[5]))
    else:
        sys.exit(f"unknown command {command}")


if __name__ == "__main__":
    main()
