"""A plain numpy nearest-neighbour reconstruction of a tracked PLUS sweep: the
speed reference for `probecal reconstruct` (benches/reconstruct.rs times both).

Usage: numpy_nn_reference.py <sequence.igs.mha> <ImageToProbe: 16 numbers> <spacing_mm> <out.mha>

Every pixel of every frame goes to its nearest voxel of a grid fitted to the
frames' corners; overlapping pixels are averaged (np.bincount); the volume is
written as an uncompressed MetaImage. No clipping, no hole filling: the plain
method, vectorised, as one would write it in numpy.
"""
import sys
import zlib

import numpy as np


def read_sequence(path):
    data = open(path, "rb").read()
    marker = b"ElementDataFile = LOCAL\n"
    start = data.index(marker) + len(marker)
    header = {}
    for line in data[:start].decode().splitlines():
        key, _, value = line.partition(" = ")
        header[key.strip()] = value.strip()
    pixels = data[start:]
    if header.get("CompressedData", "False").lower() == "true":
        pixels = zlib.decompress(pixels)
    w, h, n = (int(v) for v in header["DimSize"].split())
    frames = np.frombuffer(pixels, np.uint8).reshape(n, h, w)
    matrix = lambda key: np.array(header[key].split(), float).reshape(4, 4)
    probe = [matrix(f"Seq_Frame{i:04d}_ProbeToTrackerTransform") for i in range(n)]
    reference = [matrix(f"Seq_Frame{i:04d}_ReferenceToTrackerTransform") for i in range(n)]
    return frames, probe, reference


def main():
    sequence, image_to_probe, spacing, out = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4]
    frames, probe, reference = read_sequence(sequence)
    image_to_probe = np.array(image_to_probe.split(), float).reshape(4, 4)
    n, h, w = frames.shape
    mats = [np.linalg.inv(r) @ p @ image_to_probe for p, r in zip(probe, reference)]
    rows, cols = np.mgrid[0:h, 0:w]
    pixels = np.stack([cols.ravel(), rows.ravel(), np.zeros(h * w), np.ones(h * w)]).astype(float)
    points = [(m @ pixels)[:3] for m in mats]
    lo = np.min([p.min(axis=1) for p in points], axis=0)
    hi = np.max([p.max(axis=1) for p in points], axis=0)
    dims = np.round((hi - lo) / spacing).astype(int) + 1
    total = np.zeros(dims.prod())
    count = np.zeros(dims.prod())
    for frame, p in zip(frames, points):
        idx = np.floor((p - lo[:, None]) / spacing + 0.5).astype(int)
        flat = (idx[2] * dims[1] + idx[1]) * dims[0] + idx[0]
        total += np.bincount(flat, weights=frame.ravel(), minlength=total.size)
        count += np.bincount(flat, minlength=count.size)
    volume = np.zeros_like(total)
    np.divide(total, count, out=volume, where=count > 0)
    header = (
        "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
        f"DimSize = {dims[0]} {dims[1]} {dims[2]}\nElementSpacing = {spacing} {spacing} {spacing}\n"
        f"Offset = {lo[0]} {lo[1]} {lo[2]}\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n"
    )
    with open(out, "wb") as f:
        f.write(header.encode())
        f.write(np.floor(volume).astype(np.uint8).tobytes())


if __name__ == "__main__":
    main()
