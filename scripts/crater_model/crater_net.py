"""The crater centre-point network, its input normalisation, pyramid decoding and scoring.

Mirrors crater/src/learned_detector.cc: the C++ side must normalise, pad, decode and keep pyramid
bands exactly as here (tests/crater/learned_detector_test.cc compares the two on a real image).
"""
import math

import cv2
import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

STRIDE = 2                  # output cell size [input px]
PAD_MULTIPLE = 8            # input sizes must be multiples of this
DIAMETER_UNIT_PX = 8.0      # the size head predicts log(D / DIAMETER_UNIT_PX)
NORMALIZE_BOX_PX = 31       # local mean / std window [px of the level]
NORMALIZE_CLIP = 4.0
MIN_TRAIN_DIAMETER_PX = 4.0
LEVEL_BAND_PX = (12.0, 24.0)  # a pyramid level's own diameters [px of that level] (level 0: < 24)
LEVEL_BAND_OVERLAP = 1.25     # a level above 0 also reports down to its band's lower edge / this
MIN_LEVEL_SIZE_PX = 48      # no pyramid level smaller than this


def normalize(image):
    """Local contrast normalisation: (x - local mean) / local std over a 31 px box, clipped.
    Makes the input independent of gain, offset and bit depth (8-bit, 16-bit, float)."""
    x = image.astype(np.float32)
    k = (NORMALIZE_BOX_PX, NORMALIZE_BOX_PX)
    mean = cv2.boxFilter(x, -1, k, borderType=cv2.BORDER_REFLECT_101)
    sq = cv2.boxFilter(x * x, -1, k, borderType=cv2.BORDER_REFLECT_101)
    sd = np.sqrt(np.maximum(sq - mean * mean, 0.0)) + 1e-3 * np.abs(mean) + 1e-12
    return np.clip((x - mean) / sd, -NORMALIZE_CLIP, NORMALIZE_CLIP).astype(np.float32)


class ConvBnRelu(nn.Sequential):
    def __init__(self, cin, cout, stride=1, dilation=1):
        super().__init__(
            nn.Conv2d(cin, cout, 3, stride, padding=dilation, dilation=dilation, bias=False),
            nn.BatchNorm2d(cout), nn.ReLU(inplace=True))


class CraterNet(nn.Module):
    """Encoder to 1/8 resolution (receptive field ~75 px), two lateral-sum decoder steps back
    to 1/2; heads: sigmoid centre heat map, centre offset (cells), log diameter. With `stem`
    channels > 0, one 3 x 3 convolution at full resolution comes first."""

    def __init__(self, c=(12, 24, 32), stem=0):
        super().__init__()
        self.channels = tuple(c)
        self.stem = stem
        self.c0 = ConvBnRelu(1, stem) if stem else nn.Identity()
        self.c1 = ConvBnRelu(stem or 1, c[0], stride=2)
        self.c2 = ConvBnRelu(c[0], c[0])
        self.c3 = ConvBnRelu(c[0], c[1], stride=2)
        self.c4 = ConvBnRelu(c[1], c[1])
        self.c5 = ConvBnRelu(c[1], c[2], stride=2)
        self.c6 = ConvBnRelu(c[2], c[2])
        self.c7 = ConvBnRelu(c[2], c[2], dilation=2)
        self.lat8 = nn.Conv2d(c[2], c[1], 1)
        self.d4 = ConvBnRelu(c[1], c[1])
        self.lat4 = nn.Conv2d(c[1], c[0], 1)
        self.d2 = ConvBnRelu(c[0], c[0])
        self.head = nn.Conv2d(c[0], 4, 1)
        nn.init.constant_(self.head.bias, 0.0)
        with torch.no_grad():
            self.head.bias[0] = -2.19  # prior 0.1 on the heat map

    def forward(self, x):
        a = self.c2(self.c1(self.c0(x)))
        b = self.c4(self.c3(a))
        c = self.c7(self.c6(self.c5(b)))
        u = self.d4(F.interpolate(self.lat8(c), scale_factor=2.0, mode="nearest") + b)
        v = self.d2(F.interpolate(self.lat4(u), scale_factor=2.0, mode="nearest") + a)
        o = self.head(v)
        return torch.cat([torch.sigmoid(o[:, 0:1]), o[:, 1:4]], 1)


def load(weights_path):
    """The network of a weights file (.pt, a state dict) in eval mode, its channel counts read from
    the weights' shapes."""
    state = torch.load(weights_path)
    channels = tuple(int(state[f"{name}.0.weight"].shape[0]) for name in ("c1", "c3", "c5"))
    stem = int(state["c0.0.weight"].shape[0]) if "c0.0.weight" in state else 0
    model = CraterNet(channels, stem)
    model.load_state_dict(state)
    model.eval()
    return model


def pad_to_multiple(x):
    h, w = x.shape
    ph = (-h) % PAD_MULTIPLE
    pw = (-w) % PAD_MULTIPLE
    if ph or pw:
        x = cv2.copyMakeBorder(x, 0, ph, 0, pw, cv2.BORDER_REFLECT_101)
    return x


def decode(out, threshold):
    """Peaks of the heat map (3x3 local maxima >= threshold) as rows (x, y, diameter, score)
    in the input's pixel coordinates (centres at +0.5)."""
    heat = out[0]
    dil = cv2.dilate(heat, np.ones((3, 3), np.uint8))
    ys, xs = np.nonzero((heat >= dil) & (heat >= threshold))
    cx = (xs + out[1, ys, xs] + 0.5) * STRIDE
    cy = (ys + out[2, ys, xs] + 0.5) * STRIDE
    d = np.exp(out[3, ys, xs]) * DIAMETER_UNIT_PX
    return np.stack([cx, cy, d, heat[ys, xs]], 1).astype(np.float64)


def pyramid(image):
    levels = [image.astype(np.float32)]
    while min(levels[-1].shape) // 2 >= MIN_LEVEL_SIZE_PX:
        prev = levels[-1]
        h, w = prev.shape[0] // 2 * 2, prev.shape[1] // 2 * 2
        levels.append(cv2.resize(prev[:h, :w], (w // 2, h // 2), interpolation=cv2.INTER_AREA))
    return levels


def detect(model, image, threshold):
    """All pyramid levels, each keeping its band of diameters (reaching down into the next finer
    level's); duplicates suppressed."""
    rows = []
    for level, img in enumerate(pyramid(image)):
        h, w = img.shape
        x = pad_to_multiple(normalize(img))
        with torch.no_grad():
            out = model(torch.from_numpy(x)[None, None])[0].numpy()
        det = decode(out, threshold)
        det = det[(det[:, 0] < w) & (det[:, 1] < h)]
        lo, hi = LEVEL_BAND_PX[0] / LEVEL_BAND_OVERLAP, LEVEL_BAND_PX[1]
        if level > 0:
            det = det[det[:, 2] >= lo]
        if (min(h, w) // 2) >= MIN_LEVEL_SIZE_PX:  # not the last level
            det = det[det[:, 2] < hi]
        f = 2.0 ** level
        det[:, :3] *= f
        rows.append(det)
    det = np.concatenate(rows) if rows else np.zeros((0, 4))
    return suppress_duplicates(det)


def suppress_duplicates(det):
    """As SuppressDuplicateCraters: the more confident of two detections whose centres are
    closer than half the smaller radius with diameters within 30 %, or than half the larger
    radius with diameters within a factor 1.6 (a concentric inner edge)."""
    order = np.argsort(-det[:, 3], kind="stable")
    kept = []
    for i in order:
        x, y, d = det[i, :3]
        dup = False
        for j in kept:
            xj, yj, dj = det[j, :3]
            dist = math.hypot(x - xj, y - yj)
            lo, hi = 0.5 * min(d, dj), 0.5 * max(d, dj)
            if (dist < 0.5 * lo and hi < 1.3 * lo) or (dist < 0.5 * hi and hi < 1.6 * lo):
                dup = True
                break
        if not dup:
            kept.append(i)
    return det[kept]


def match(truth, det):
    """Greedy one-to-one matching as ScoreCraters: a pair when the centre lies within half the
    true radius and the diameter within 30 %, by increasing distance / radius + |ratio - 1|.
    Returns (truth index, detection index) pairs."""
    cand = []
    for t, (tx, ty, td) in enumerate(truth):
        r = 0.5 * td
        dist = np.hypot(det[:, 0] - tx, det[:, 1] - ty)
        ratio = det[:, 2] / td
        for k in np.nonzero((dist < 0.5 * r) & (ratio >= 0.7) & (ratio <= 1.3))[0]:
            cand.append((dist[k] / r + abs(ratio[k] - 1), t, k))
    cand.sort()
    used_t, used_k, pairs = set(), set(), []
    for _, t, k in cand:
        if t in used_t or k in used_k:
            continue
        used_t.add(t)
        used_k.add(k)
        pairs.append((t, k))
    return pairs


def score(truth, det, min_diameter):
    """Returns ((matched truth, matched detections) >= min_diameter, detections, truth)."""
    pairs = match(truth, det)
    mt = sum(1 for t, _ in pairs if truth[t, 2] >= min_diameter)
    md = sum(1 for _, k in pairs if det[k, 2] >= min_diameter)
    return (mt, md), int((det[:, 2] >= min_diameter).sum()), int((truth[:, 2] >= min_diameter).sum())


def precision_recall_f1(matched_truth, matched_detections, detections, truth):
    """P, R and F1 from the counts that `score` returns (0 where a count is 0)."""
    p = matched_detections / max(detections, 1)
    r = matched_truth / max(truth, 1)
    return p, r, 2 * p * r / max(p + r, 1e-9)


def export_onnx(model, path):
    model.eval()
    x = torch.zeros(1, 1, 64, 64)
    torch.onnx.export(model, x, path, input_names=["image"], output_names=["out"],
                      opset_version=11, do_constant_folding=True,
                      dynamic_axes={"image": {2: "h", 3: "w"}, "out": {2: "h2", 3: "w2"}})
