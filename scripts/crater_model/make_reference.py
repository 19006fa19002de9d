#!/usr/bin/env python3
"""Writes tests/data/crater_net_reference.csv: the network's circles (PyTorch, no rim fits) on a
256 x 256 crop of the HRSC test image, which tests/crater/learned_detector_test.cc compares with
the C++ port (OpenCV dnn). Run after retraining:
    /usr/bin/python3 scripts/crater_model/make_reference.py ../shared/data crater/models/crater_centernet.pt
"""
import os
import sys

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import crater_net  # noqa: E402

X0, Y0, SIZE = 700, 300, 256  # the crop; the test holds the same numbers


def main():
    data, weights = sys.argv[1], sys.argv[2]
    model = crater_net.load(weights)
    image = cv2.imread(os.path.join(data, "craters", "hrsc_nanedi_north.png"), cv2.IMREAD_UNCHANGED)
    crop = image[Y0:Y0 + SIZE, X0:X0 + SIZE].astype(np.float32)
    threshold = float(sys.argv[3]) if len(sys.argv) > 3 else 0.35
    det = crater_net.detect(model, crop, threshold)
    det = det[det[:, 2] >= 4.0]
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
    out = os.path.join(root, "tests", "data", "crater_net_reference.csv")
    with open(out, "w") as f:
        f.write("x_px,y_px,diameter_px,score\n")
        for x, y, d, s in det:
            f.write(f"{x:.6f},{y:.6f},{d:.6f},{s:.6f}\n")
    print(f"wrote {out}: {len(det)} craters")


if __name__ == "__main__":
    main()
