#!/usr/bin/env python3
"""How well people agree on the held-out CTX craters, and where the network stands among them
(issue #43's CTX target, docs/notes/2026-12-07-crater-annotator-agreement.md):

    /usr/bin/python3 scripts/crater_model/annotator_agreement.py CATALOGUE ../shared/data \
        [WEIGHTS.pt] [THRESHOLD]

CATALOGUE is a checkout of the Mars crater catalogue (GitHub aliFrancis/mars-crater-catalogue,
CC-BY-4.0); its data/annotations/raw/MC11E-X/*.xml hold each of the six annotators' boxes and
data/annotations/expert/MC11E-X.xml an expert's. They are not in ../shared/data.

For each held-out image and each annotator, the other five annotators' boxes are merged as the
catalogue merged all six (average-linkage clustering on 1 - IoU of the boxes' circles, same
annotator never merged, cut at 0.9), and the clusters of >= 2 of them are the truth. The annotator's
own boxes, and the network's circles, are then scored against that truth with the rule of
crater_score.h (centre within half the true radius, diameter within 30 %, craters >= 8 px): a
person and the network are measured on exactly the same labels. The expert's boxes are scored
against the published >= 2 consensus of the six, as the network is in the model card. Merging all
six with this code reproduces the catalogue's clusters (a printed check).
"""
import glob
import os
import sys
import xml.etree.ElementTree as ET

import cv2
import numpy as np
import torch
from scipy.cluster.hierarchy import fcluster, linkage

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import crater_net  # noqa: E402
from evaluate import labels  # noqa: E402
from train import HELD_OUT  # noqa: E402

CLUSTER_CUT = 0.9        # the catalogue's distance threshold (1 - IoU)
MIN_AGREED = 2           # annotators that make a crater a label, as #43 scores
MIN_DIAMETER_PX = 8.0
SAME_ANNOTATOR = 1e9     # distance that keeps one annotator's boxes apart


def read_boxes(xml_path):
    """Circles (x, y, D) [px] of a PASCAL VOC file: centre of the box, D = mean side."""
    rows = []
    try:
        for box in ET.parse(xml_path).getroot().iter("bndbox"):
            x0, y0, x1, y1 = (float(box.find(k).text) for k in ("xmin", "ymin", "xmax", "ymax"))
            rows.append(((x0 + x1) / 2, (y0 + y1) / 2, ((x1 - x0) + (y1 - y0)) / 2))
    except (ET.ParseError, AttributeError, TypeError, ValueError) as e:
        raise SystemExit(f"error: {xml_path}: not a PASCAL VOC file with numeric "
                         f"<bndbox> xmin/ymin/xmax/ymax ({e})")
    if not rows:
        raise SystemExit(f"error: {xml_path}: no <bndbox> elements")
    return np.array(rows)


def circle_iou(a, b):
    """IoU of every circle in a (N, 3) with every circle in b (M, 3): (N, M)."""
    r1, r2 = a[:, None, 2] / 2, b[None, :, 2] / 2
    d = np.hypot(a[:, None, 0] - b[None, :, 0], a[:, None, 1] - b[None, :, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        c1 = np.clip((d * d + r1 * r1 - r2 * r2) / (2 * d * r1), -1, 1)
        c2 = np.clip((d * d + r2 * r2 - r1 * r1) / (2 * d * r2), -1, 1)
        lens = (r1 * r1 * np.arccos(c1) + r2 * r2 * np.arccos(c2)
                - 0.5 * np.sqrt(np.clip((-d + r1 + r2) * (d + r1 - r2) * (d - r1 + r2)
                                        * (d + r1 + r2), 0, None)))
    inter = np.where(d >= r1 + r2, 0.0,
                     np.where(d <= np.abs(r1 - r2), np.pi * np.minimum(r1, r2) ** 2, lens))
    return inter / (np.pi * r1 * r1 + np.pi * r2 * r2 - inter)


def merge(annotators):
    """Merges a list of (N_i, 3) circle arrays, one per annotator. Returns (circles, count):
    the mean circle of each cluster and how many annotators it holds."""
    circles = np.concatenate(annotators)
    who = np.concatenate([np.full(len(a), i) for i, a in enumerate(annotators)])
    dist = np.clip(1.0 - circle_iou(circles, circles), 0.0, 1.0)
    dist[who[:, None] == who[None, :]] = SAME_ANNOTATOR
    np.fill_diagonal(dist, 0.0)
    condensed = dist[np.triu_indices(len(circles), 1)]
    ids = fcluster(linkage(condensed, method="average"), CLUSTER_CUT, criterion="distance")
    _, cluster, count = np.unique(ids, return_inverse=True, return_counts=True)
    merged = np.zeros((len(count), 3))
    np.add.at(merged, cluster, circles)
    return merged / count[:, None], count


def score(truth, circles):
    (mt, md), nd, nt = crater_net.score(truth, circles, MIN_DIAMETER_PX)
    return np.array([mt, md, nd, nt], float)


def fmt(counts):
    return "P {:.3f} R {:.3f} F1 {:.3f}".format(*crater_net.precision_recall_f1(*counts))


def main():
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    catalogue, data = sys.argv[1], sys.argv[2]
    weights = sys.argv[3] if len(sys.argv) > 3 else os.path.join(
        os.path.dirname(os.path.abspath(__file__)), "../../crater/models/crater_centernet.pt")
    threshold = float(sys.argv[4]) if len(sys.argv) > 4 else 0.4
    torch.set_num_threads(2)
    model = crater_net.load(weights)
    ctx = os.path.join(data, "craters-train/ctx-mc11e")
    people, network, expert, network_cat = (np.zeros(4) for _ in range(4))
    per_person = []
    for image in HELD_OUT:
        raw = os.path.join(catalogue, f"data/annotations/raw/MC11E-{image}")
        files = sorted(glob.glob(os.path.join(raw, "*.xml")))
        if len(files) != 6:
            raise SystemExit(f"error: {raw}: expected the six annotators' XML files, found "
                             f"{len(files)}")
        boxes = [read_boxes(f) for f in files]
        published = labels(os.path.join(ctx, f"MC11E-{image}_craters.csv"), 1)
        _, count = merge(boxes)
        print(f"MC11E-{image}: {len(count)} clusters of the six (catalogue: {len(published)}); "
              f"by number of annotators 1..6: {np.bincount(count, minlength=7)[1:].tolist()}")
        pixels = cv2.imread(os.path.join(ctx, f"MC11E-{image}.png"), cv2.IMREAD_UNCHANGED)
        det = crater_net.detect(model, pixels.astype(np.float32), threshold)[:, :3]
        for k, own in enumerate(boxes):
            merged, count = merge([b for j, b in enumerate(boxes) if j != k])
            truth = merged[count >= MIN_AGREED]
            person, net = score(truth, own), score(truth, det)
            people += person
            network += net
            per_person.append((crater_net.precision_recall_f1(*person)[2],
                               crater_net.precision_recall_f1(*net)[2]))
            name = os.path.basename(files[k])[:-4]
            print(f"  annotator {name}: {int(person[3])} labels of the other five; "
                  f"annotator {fmt(person)} | network {fmt(net)}")
        expert_file = os.path.join(catalogue, f"data/annotations/expert/MC11E-{image}.xml")
        if os.path.exists(expert_file):
            consensus = labels(os.path.join(ctx, f"MC11E-{image}_craters.csv"), MIN_AGREED)
            e, n = score(consensus, read_boxes(expert_file)), score(consensus, det)
            expert += e
            network_cat += n
            print(f"  expert against the catalogue's >= 2: {fmt(e)} | network {fmt(n)}")
    f1 = np.array(per_person)
    print(f"pooled, each annotator against the other five: people {fmt(people)} | "
          f"network {fmt(network)}")
    print(f"median over the {len(f1)} (image, annotator) pairs: people F1 "
          f"{np.median(f1[:, 0]):.3f} | network F1 {np.median(f1[:, 1]):.3f}; the network "
          f"scores higher in {int((f1[:, 1] > f1[:, 0]).sum())} of them")
    if expert[3] > 0:
        print(f"expert images pooled: expert {fmt(expert)} | network {fmt(network_cat)}")


if __name__ == "__main__":
    main()
