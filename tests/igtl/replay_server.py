#!/usr/bin/env python3
"""Broadcasts a PLUS sequence file over OpenIGTLink as PlusServer does, with
pyigtl (an implementation independent of probecal's): per frame an IMAGE from
device `Image` and a TRANSFORM per valid transform (PlusServer's
SendValidTransformsOnly), all stamped with the frame's timestamp, paced at
`--speed` times the recorded rate; then a STRING from `SequenceEnd`. It then
waits for the client's `ImageToProbe` TRANSFORM and writes what it sent and
received to `--report` (JSON). Binds to loopback only.

    replay_server.py SEQUENCE.mha --port P --speed 4 --report out.json
"""
import argparse
import json
import re
import sys
import time
import zlib

import numpy as np
import pyigtl


def read_sequence(path):
    """The header fields and the frames' pixels of an 8-bit PLUS sequence file."""
    data = open(path, "rb").read()
    fields, offset = {}, 0
    while True:
        end = data.index(b"\n", offset)
        line = data[offset:end].decode().strip()
        offset = end + 1
        if not line:
            continue
        key, value = [p.strip() for p in line.split("=", 1)]
        if key == "ElementDataFile":
            break
        fields[key] = value
    w, h, n = [int(v) for v in fields["DimSize"].split()]
    assert fields["ElementType"] == "MET_UCHAR", "8-bit sequences only"
    pixels = data[offset:]
    if fields.get("CompressedData", "False") == "True":
        pixels = zlib.decompress(pixels)
    frames = np.frombuffer(pixels[: w * h * n], dtype=np.uint8).reshape(n, h, w)
    orientation = fields.get("UltrasoundImageOrientation", "MF")[:2]
    if orientation[0] == "U":
        frames = frames[:, :, ::-1]
    if orientation[1] == "N":
        frames = frames[:, ::-1, :]
    per_frame = {}
    for key, value in fields.items():
        m = re.match(r"Seq_Frame(\d+)_(.+)", key)
        if m:
            per_frame.setdefault(int(m.group(1)), {})[m.group(2)] = value
    return frames, [per_frame[i] for i in range(n)]


def main():
    p = argparse.ArgumentParser()
    p.add_argument("sequence")
    p.add_argument("--port", type=int, required=True)
    p.add_argument("--speed", type=float, default=1.0)
    p.add_argument("--report", required=True)
    p.add_argument("--wait-client-s", type=float, default=60.0)
    a = p.parse_args()
    frames, per_frame = read_sequence(a.sequence)
    server = pyigtl.OpenIGTLinkServer(port=a.port, local_server=True)
    print("listening", flush=True)
    deadline = time.time() + a.wait_client_s
    while not server.is_connected():
        if time.time() > deadline:
            sys.exit("no client connected")
        time.sleep(0.01)
    times = [float(f["Timestamp"]) for f in per_frame]
    start = time.monotonic()
    sent = {"images": 0, "transforms": 0}
    for image, fields, t in zip(frames, per_frame, times):
        due = (t - times[0]) / a.speed
        wait = due - (time.monotonic() - start)
        if wait > 0:
            time.sleep(wait)
        server.send_message(
            pyigtl.ImageMessage(np.ascontiguousarray(image[np.newaxis, :, :]), timestamp=t, device_name="Image"),
            wait=False,
        )
        sent["images"] += 1
        for key, value in sorted(fields.items()):
            if not key.endswith("Transform") or fields.get(key + "Status", "OK") != "OK":
                continue
            matrix = np.array([float(v) for v in value.split()]).reshape(4, 4)
            name = key[: -len("Transform")]
            server.send_message(pyigtl.TransformMessage(matrix, timestamp=t, device_name=name), wait=False)
            sent["transforms"] += 1
    server.send_message(pyigtl.StringMessage("end", timestamp=times[-1], device_name="SequenceEnd"), wait=True)
    reply = server.wait_for_message("ImageToProbe", timeout=300)
    report = {
        "frames": len(per_frame),
        "images_sent": sent["images"],
        "transforms_sent": sent["transforms"],
        "seconds": time.monotonic() - start,
        "image_to_probe": None if reply is None else np.asarray(reply.matrix).tolist(),
    }
    json.dump(report, open(a.report, "w"), indent=1)
    server.stop()


if __name__ == "__main__":
    main()
