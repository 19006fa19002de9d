#!/usr/bin/env python3
"""Scores a trained crater network (PyTorch weights, no rim fits) on labelled images and measures
its circles' errors, the numbers behind the model card (docs/crater-model.md):

    /usr/bin/python3 scripts/crater_model/evaluate.py WEIGHTS.pt ../shared/data [THRESHOLD]

Prints P/R/F1 for craters >= 8 px per image: the three held-out CTX images (labels of >= 2
annotators), the HRSC image in craters/ and the five hrsc-bandeira crops (measured, never trained
or tuned on); and, on the held-out CTX images, the robust 1-sigma (1.4826 x median absolute) of the
matched circles' centre error per axis and diameter error, as fractions of the true diameter:
the sigmas learned_detector.cc gives the circles it keeps.
"""
import glob
import os
import sys

import cv2
import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import crater_net  # noqa: E402
from train import HELD_OUT  # noqa: E402


def labels(path, min_annotators):
    rows = np.genfromtxt(path, delimiter=",", names=True)
    cols = [rows["x_px"], rows["y_px"], rows["diameter_px"]]
    out = np.stack(cols, 1)
    if "annotators" in rows.dtype.names:
        out = out[rows["annotators"] >= min_annotators]
    return out


def main():
    weights, data = sys.argv[1], sys.argv[2]
    threshold = float(sys.argv[3]) if len(sys.argv) > 3 else 0.35
    torch.set_num_threads(2)
    model = crater_net.load(weights)
    sets = [("ctx-held-out", os.path.join(data, "craters-train/ctx-mc11e", f"MC11E-{c}.png"), 2)
            for c in HELD_OUT]
    sets.append(("hrsc-north", os.path.join(data, "craters/hrsc_nanedi_north.png"), 0))
    for p in sorted(glob.glob(os.path.join(data, "craters-train/hrsc-bandeira/*.png"))):
        sets.append(("hrsc-bandeira", p, 0))
    errors = []
    pooled = {}
    for name, path, min_annotators in sets:
        image = cv2.imread(path, cv2.IMREAD_UNCHANGED).astype(np.float32)
        truth = labels(path[:-4] + "_craters.csv", min_annotators)
        det = crater_net.detect(model, image, threshold)
        (mt, md), nd, nt = crater_net.score(truth, det[:, :3], 8.0)
        p, r, f1 = crater_net.precision_recall_f1(mt, md, nd, nt)
        print(f"{name:14s} {os.path.basename(path):18s} truth {nt:5d} det {nd:5d} "
              f"P {p:.3f} R {r:.3f} F1 {f1:.3f}", flush=True)
        acc = pooled.setdefault(name, [0, 0, 0, 0])
        for i, v in enumerate((mt, md, nd, nt)):
            acc[i] += v
        if name == "ctx-held-out":
            for t, k in crater_net.match(truth, det[:, :3]):
                if truth[t, 2] < 8.0:
                    continue
                d = truth[t, 2]
                errors.append(((det[k, 0] - truth[t, 0]) / d, (det[k, 1] - truth[t, 1]) / d,
                               (det[k, 2] - d) / d))
    for name, (mt, md, nd, nt) in pooled.items():
        p, r, f1 = crater_net.precision_recall_f1(mt, md, nd, nt)
        print(f"pooled {name:14s} P {p:.3f} R {r:.3f} F1 {f1:.3f}")
    e = np.array(errors)
    sigma = 1.4826 * np.median(np.abs(e - np.median(e, 0)), 0)
    print(f"circle errors on the held-out CTX images ({len(e)} matches), robust sigma / D: "
          f"x {sigma[0]:.3f} y {sigma[1]:.3f} diameter {sigma[2]:.3f}; median diameter bias "
          f"{np.median(e[:, 2]):+.3f}")


if __name__ == "__main__":
    main()
