#!/usr/bin/env python3
"""Times OpenCV's board search photo by photo, as benches/opencv_reference.py
searches (both 10x10 boards per photo, `findChessboardCorners` on a half-size
copy, the found board painted over before the next search), on one thread. It
prints the OpenCV version, every photo whose searches take over 50 ms, and the
total over the dataset, so that the search's cost under one OpenCV can be set
against another's. Usage: board_search_by_frame.py <rendered dataset folder>
"""

import sys
import time
from pathlib import Path

import cv2
import numpy as np

from opencv_reference import PROBE_BOARD


def main():
    cv2.setNumThreads(1)
    folder = Path(sys.argv[1])
    total_s = 0.0
    photos = sorted((folder / "frames").glob("camera_*.png"))
    print(f"OpenCV {cv2.__version__}, {len(photos)} photos")
    for photo in photos:
        grey = cv2.imread(str(photo), cv2.IMREAD_GRAYSCALE)
        half = cv2.resize(grey, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
        searches = []
        for _ in range(2):
            start = time.perf_counter()
            found, corners = cv2.findChessboardCorners(half, PROBE_BOARD, flags=cv2.CALIB_CB_ADAPTIVE_THRESH)
            searches.append((found, time.perf_counter() - start))
            if not found:
                break
            hull = cv2.convexHull(corners.reshape(-1, 2).astype(np.int32))
            cv2.fillConvexPoly(half, hull, 128)
        spent = sum(s for _, s in searches)
        total_s += spent
        if spent > 0.05:
            words = ", ".join(f"{'found' if f else 'not found'} in {s * 1000:.0f} ms" for f, s in searches)
            print(f"{photo.name}: {words}")
    print(f"all searches: {total_s:.3f} s")


if __name__ == "__main__":
    main()
