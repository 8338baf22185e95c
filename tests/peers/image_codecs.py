"""OpenCV's own reading and writing of images, the peer of tests/image_codecs.rs.

Usage: image_codecs.py <out folder> <shared data folder>

Writes into <out folder> PNGs of every colour type and bit depth (with and
without a gamma chunk) and JPEGs of several kinds, then, for each of them and
for every PNG and JPEG of the shared data, OpenCV's `imread(IMREAD_GRAYSCALE)`
as `<name>.grey` (width and height as two little-endian u32, then the pixels),
listed in `cases.txt` (path, then its .grey). It also writes OpenCV's
`imencode(".jpg", quality 80)` of two images as `encode_*.raw` (width, height,
channels as u32, then the pixels) and `encode_*.jpg`.
"""
import glob
import os
import struct
import sys
import zlib

import cv2
import numpy as np

out, shared = sys.argv[1], sys.argv[2]
rng = np.random.default_rng(11)


def chunk(kind, body):
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)


def png(name, width, height, colour_type, depth, rows, extra=b""):
    """A PNG written by hand: `rows` are the packed bytes of each row."""
    raw = b"".join(b"\0" + bytes(r) for r in rows)
    ihdr = struct.pack(">IIBBBBB", width, height, depth, colour_type, 0, 0, 0)
    data = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + extra + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")
    path = os.path.join(out, name)
    open(path, "wb").write(data)
    return path


w, h = 37, 23
cases = []
grey8 = rng.integers(0, 256, (h, w), dtype=np.uint8)
rgb8 = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
rgb8[::4] = rgb8[::4, :, :1]  # some rows with equal channels
alpha = rng.integers(0, 256, (h, w, 1), dtype=np.uint8)
rgb16 = rng.integers(0, 65536, (h, w, 3), dtype=np.uint16)
grey16 = rng.integers(0, 65536, (h, w), dtype=np.uint16)
gama = chunk(b"gAMA", struct.pack(">I", 45455))
srgb = chunk(b"sRGB", b"\0")
gama_18 = chunk(b"gAMA", struct.pack(">I", 55556))
gama_1 = chunk(b"gAMA", struct.pack(">I", 100000))
cases.append(png("grey8.png", w, h, 0, 8, grey8))
cases.append(png("grey16.png", w, h, 0, 16, grey16.astype(">u2").view(np.uint8).reshape(h, -1)))
for bits in (1, 2, 4):
    levels = rng.integers(0, 1 << bits, (h, w), dtype=np.uint8)
    packed = [np.packbits(np.unpackbits(r[:, None], axis=1)[:, 8 - bits:].ravel()) for r in levels]
    cases.append(png(f"grey{bits}bit.png", w, h, 0, bits, packed))
cases.append(png("grey_trns.png", w, h, 0, 8, grey8, chunk(b"tRNS", b"\0\x07")))
cases.append(png("grey_alpha.png", w, h, 4, 8, np.dstack([grey8, alpha]).reshape(h, -1)))
for name, extra in (("rgb8", b""), ("rgb8_gama", gama), ("rgb8_srgb", srgb), ("rgb8_gama18", gama_18), ("rgb8_gama1", gama_1)):
    cases.append(png(f"{name}.png", w, h, 2, 8, rgb8.reshape(h, -1), extra))
cases.append(png("rgba8.png", w, h, 6, 8, np.dstack([rgb8, alpha]).reshape(h, -1)))
cases.append(png("rgba8_gama.png", w, h, 6, 8, np.dstack([rgb8, alpha]).reshape(h, -1), gama))
cases.append(png("rgb16.png", w, h, 2, 16, rgb16.astype(">u2").view(np.uint8).reshape(h, -1)))
palette = rng.integers(0, 256, (16, 3), dtype=np.uint8)
index = rng.integers(0, 16, (h, w), dtype=np.uint8)
plte = chunk(b"PLTE", palette.tobytes())
cases.append(png("palette8.png", w, h, 3, 8, index, plte))
cases.append(png("palette8_trns.png", w, h, 3, 8, index, plte + chunk(b"tRNS", bytes(range(0, 160, 10)))))
packed4 = [np.packbits(np.unpackbits(r[:, None], axis=1)[:, 4:].ravel()) for r in index]
cases.append(png("palette4.png", w, h, 3, 4, packed4, plte))

bgr_photo = cv2.imread(os.path.join(shared, "opencv-aruco", "gboriginal.png"))
grey_photo = cv2.cvtColor(bgr_photo, cv2.COLOR_BGR2GRAY)
for name, image, params in (
    ("colour_q90.jpg", bgr_photo, [cv2.IMWRITE_JPEG_QUALITY, 90]),
    ("colour_progressive.jpg", bgr_photo, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1]),
    ("grey_q60.jpg", grey_photo, [cv2.IMWRITE_JPEG_QUALITY, 60]),
    ("grey_restart.jpg", grey_photo, [cv2.IMWRITE_JPEG_RST_INTERVAL, 4]),
):
    path = os.path.join(out, name)
    assert cv2.imwrite(path, image, params)
    cases.append(path)
cases += sorted(glob.glob(os.path.join(shared, "**", "*.jpg"), recursive=True))
cases += sorted(glob.glob(os.path.join(shared, "**", "*.png"), recursive=True))

with open(os.path.join(out, "cases.txt"), "w") as listing:
    for n, path in enumerate(cases):
        grey = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        assert grey is not None and grey.dtype == np.uint8, path
        ref = os.path.join(out, f"case{n:03d}.grey")
        open(ref, "wb").write(struct.pack("<II", grey.shape[1], grey.shape[0]) + grey.tobytes())
        listing.write(f"{path}\t{ref}\n")

for name, image in (("grey", grey_photo), ("colour", bgr_photo)):
    channels = 1 if image.ndim == 2 else 3
    raw = struct.pack("<III", image.shape[1], image.shape[0], channels) + np.ascontiguousarray(image).tobytes()
    open(os.path.join(out, f"encode_{name}.raw"), "wb").write(raw)
    ok, jpeg = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 80])
    assert ok
    open(os.path.join(out, f"encode_{name}.jpg"), "wb").write(jpeg.tobytes())
print(len(cases))
