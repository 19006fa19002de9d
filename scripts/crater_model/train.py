#!/usr/bin/env python3
"""Trains areomap's learned crater detector and exports it to ONNX.

The model is a small fully convolutional centre-point network (CenterNet-style): from one
locally normalised image channel it predicts, at half the input resolution, a crater-centre
heat map, the centre's sub-cell offset and the log rim diameter. crater/src/learned_detector.cc
runs it through OpenCV dnn on an image pyramid; docs/crater-model.md says why this design.

Data: the CTX MC-11 East catalogue (../shared/data/craters-train/ctx-mc11e, CC-BY-4.0), nine
images for training and three held out for validation (HELD_OUT below), and, with --generated,
scenes from the mission generator (build/release/eval/areomap_crater_training_scenes), drawn for a
--generated-fraction of the crops. The built-in model is trained on nothing else: the HRSC
images in ../shared/data are for measurement only.

A model for your own sensor: --extra DIR adds your labelled images (NAME.png with
NAME_craters.csv: x_px,y_px,diameter_px[,annotators]) for an --extra-fraction of the crops, and
--validate DIR chooses the checkpoint and threshold on other labelled images of yours; then run
`areomap craters --model OUT.onnx --min-score THRESHOLD` with the threshold this script prints.

Usage (Debian's python3-torch and python3-opencv; `bash scripts/install-deps.sh --training`):
    build/release/eval/areomap_crater_training_scenes --out build/crater-scenes --count 64
    /usr/bin/python3 scripts/crater_model/train.py --data ../shared/data/craters-train/ctx-mc11e \
        --generated build/crater-scenes --out crater/models/crater_centernet.onnx
Deterministic for a given --seed on one machine (torch CPU, fixed thread count).
"""
import argparse
import glob
import json
import math
import os
import sys
import time

import cv2
import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import crater_net  # noqa: E402

ALL_IMAGES = "ABCDEFGHIJKL"
HELD_OUT = "CFL"  # validation images, never trained on


AGREED = 6  # the annotator count given to labels that carry none: every crater is certain


def load_labelled_image(stem):
    """stem.png and stem_craters.csv (x_px, y_px, diameter_px[, annotators]; pixel centres at
    +0.5) as (name, float32 image, N x 4 craters). Without an annotators column every crater
    counts as agreed on."""
    image = cv2.imread(stem + ".png", cv2.IMREAD_UNCHANGED)
    if image is None or image.ndim != 2:
        raise SystemExit(f"error: {stem}.png is not a readable one-channel image")
    csv = stem + "_craters.csv"
    if not os.path.exists(csv):
        raise SystemExit(f"error: {csv} is missing (x_px,y_px,diameter_px[,annotators])")
    rows = np.genfromtxt(csv, delimiter=",", names=True, ndmin=1)
    for column in ("x_px", "y_px", "diameter_px"):
        if rows.dtype.names is None or column not in rows.dtype.names:
            raise SystemExit(f"error: {csv} has no column {column}")
    annotators = (rows["annotators"] if "annotators" in rows.dtype.names
                  else np.full(len(rows), AGREED, np.float64))
    craters = np.stack([rows["x_px"], rows["y_px"], rows["diameter_px"], annotators], 1)
    if not np.isfinite(craters).all():
        raise SystemExit(f"error: {csv} holds a value that is not a finite number")
    return os.path.basename(stem), image.astype(np.float32), craters


def load_catalogue(data_dir, letters):
    return [load_labelled_image(os.path.join(data_dir, f"MC11E-{letter}")) for letter in letters]


def load_folder(folder, pattern="*.png"):
    """Every image of `folder` matching `pattern` with its NAME_craters.csv."""
    paths = sorted(glob.glob(os.path.join(folder, pattern)))
    if not paths:
        raise SystemExit(f"error: {folder} holds no {pattern}")
    return [load_labelled_image(p[:-4]) for p in paths]


def load_generated(folder):
    """Generated scenes: scene-NNN.png (16-bit DN) with scene-NNN_craters.csv, every crater
    labelled (annotators = 6)."""
    return load_folder(folder, "scene-*.png")


def crater_count_weights(items):
    """Images with more craters are drawn more often, but every image is drawn."""
    counts = np.array([max(50, len(c)) for _, _, c in items], np.float64)
    return counts / counts.sum()


class Sampler:
    """Random training crops with their crater labels, augmented as real products differ:
    scale (GSD), rotation by quarter turns and flips (sun direction), blur (MTF), noise, gain.
    Crops come from the catalogue `items`, from `generated` scenes for a `generated_fraction` of
    them and from a user's `extra` labelled images for an `extra_fraction` (both shares of all
    crops)."""

    def __init__(self, items, crop, rng, min_prefilter=0.5, sharpen=0.0, generated=(),
                 generated_fraction=0.0, extra=(), extra_fraction=0.0):
        self.min_prefilter = min_prefilter
        self.sharpen = sharpen
        self.items = items
        self.generated = list(generated)
        self.generated_fraction = generated_fraction if self.generated else 0.0
        self.extra = list(extra)
        self.extra_fraction = extra_fraction if self.extra else 0.0
        if self.generated_fraction + self.extra_fraction >= 1.0:
            raise SystemExit("error: --generated-fraction plus --extra-fraction must stay under 1")
        self.crop = crop
        self.rng = rng
        self.weights = crater_count_weights(items)
        self.extra_weights = crater_count_weights(self.extra) if self.extra else None

    def sample(self):
        rng = self.rng
        if self.generated_fraction > 0.0 and rng.random() < self.generated_fraction:
            _, image, craters = self.generated[rng.integers(len(self.generated))]
        elif (self.extra_fraction > 0.0
              and rng.random() < self.extra_fraction / (1.0 - self.generated_fraction)):
            _, image, craters = self.extra[rng.choice(len(self.extra), p=self.extra_weights)]
        else:
            _, image, craters = self.items[rng.choice(len(self.items), p=self.weights)]
        # Output/input scale: mostly near the native GSD, sometimes much coarser, so that
        # large craters are seen at the sizes the pyramid shows them.
        if rng.random() < 0.3:
            scale = math.exp(rng.uniform(math.log(0.2), math.log(0.5)))
        else:
            scale = math.exp(rng.uniform(math.log(0.5), math.log(1.2)))
        src = self.crop / scale
        h, w = image.shape
        src = min(src, h - 1, w - 1)
        scale = self.crop / src
        x0 = rng.uniform(0, w - src)
        y0 = rng.uniform(0, h - src)
        # Affine on pixel indices: output = scale * (input - origin).
        m = np.array([[scale, 0, -scale * x0], [0, scale, -scale * y0]], np.float32)
        # Low-pass before decimation: from none to the pyramid's 2x2 averaging (sigma ~0.5 px of
        # the output), because a sensor's native image is as sharp as its pixels allow, which a
        # downsampled CTX crop is not unless the prefilter is weak.
        sigma = (rng.uniform(self.min_prefilter, 0.5) if self.min_prefilter < 0.5 else 0.5) / scale
        if scale < 1.0 and sigma > 0.3:
            k = int(2 * math.ceil(2 * sigma) + 1)
            ys, xs = int(max(0, y0 - k)), int(max(0, x0 - k))
            ye, xe = int(min(h, y0 + src + k + 1)), int(min(w, x0 + src + k + 1))
            patch = cv2.GaussianBlur(image[ys:ye, xs:xe], (k, k), sigma)
            m[0, 2] += scale * xs
            m[1, 2] += scale * ys
        else:
            patch, xs, ys = image, 0, 0
        out = cv2.warpAffine(patch, m, (self.crop, self.crop), flags=cv2.INTER_LINEAR,
                             borderMode=cv2.BORDER_REFLECT)
        # Photometric: gain, gamma, blur, noise.
        lo, hi = np.percentile(out, [1, 99])
        out = (out - lo) / max(hi - lo, 1.0)
        out = np.clip(out, 0, 1) ** math.exp(rng.uniform(-0.4, 0.4))
        if rng.random() < 0.5:
            s = rng.uniform(0.3, 1.2)
            out = cv2.GaussianBlur(out, (0, 0), s)
        elif self.sharpen > 0.0 and rng.random() < 0.5:
            # Unsharp masking: the crisp, high-contrast texture of sensors such as HRSC.
            out = out + rng.uniform(0.0, self.sharpen) * (out - cv2.GaussianBlur(out, (0, 0), 1.0))
        out = out + rng.normal(0, rng.uniform(0, 0.04), out.shape).astype(np.float32)
        out = out * rng.uniform(20, 200)
        # Label coordinates have pixel centres at +0.5; warpAffine's at integers.
        cx = scale * (craters[:, 0] - 0.5 - x0) + 0.5
        cy = scale * (craters[:, 1] - 0.5 - y0) + 0.5
        d = scale * craters[:, 2]
        labels = np.stack([cx, cy, d, craters[:, 3]], 1)
        keep = (cx > -d) & (cy > -d) & (cx < self.crop + d) & (cy < self.crop + d)
        labels = labels[keep]
        # Quarter turns and flips.
        k = int(rng.integers(4))
        flip = bool(rng.integers(2))
        out, labels = rotate_flip(out, labels, k, flip)
        return crater_net.normalize(out), labels


def rotate_flip(image, labels, quarter_turns, flip):
    n = image.shape[0]
    labels = labels.copy()
    for _ in range(quarter_turns):
        image = np.rot90(image)  # counter-clockwise: (x, y) -> (y, n - x)
        x, y = labels[:, 0].copy(), labels[:, 1].copy()
        labels[:, 0], labels[:, 1] = y, n - x
    if flip:
        image = image[:, ::-1]
        labels[:, 0] = n - labels[:, 0]
    return np.ascontiguousarray(image), labels


def targets(labels, size, min_annotators, max_net_diameter):
    """Heat map (Gaussian per crater), ignore mask, and regression targets at half resolution."""
    s = crater_net.STRIDE
    n = size // s
    heat = np.zeros((n, n), np.float32)
    weight = np.ones((n, n), np.float32)
    reg = np.zeros((3, n, n), np.float32)
    reg_mask = np.zeros((n, n), np.float32)
    yy, xx = np.mgrid[0:n, 0:n].astype(np.float32)
    for cx, cy, d, annotators in labels:
        gx, gy, gd = cx / s - 0.5, cy / s - 0.5, d / s  # cell-centre coordinates
        r = 0.5 * gd + 2
        x0, x1 = int(max(0, math.floor(gx - r))), int(min(n, math.ceil(gx + r) + 1))
        y0, y1 = int(max(0, math.floor(gy - r))), int(min(n, math.ceil(gy + r) + 1))
        if x0 >= x1 or y0 >= y1:
            continue
        doubtful = annotators < min_annotators or d < crater_net.MIN_TRAIN_DIAMETER_PX
        if doubtful or d > max_net_diameter:
            # Neither crater nor background: only some annotators saw it, or the network is
            # not asked to find it at this scale (the pyramid's next level will).
            rr = max(1.0, 0.35 * gd)
            inside = (xx[y0:y1, x0:x1] - gx) ** 2 + (yy[y0:y1, x0:x1] - gy) ** 2 <= rr * rr
            weight[y0:y1, x0:x1][inside] = 0.0
            continue
        sigma = max(0.5, gd / 6.0)
        g = np.exp(-((xx[y0:y1, x0:x1] - gx) ** 2 + (yy[y0:y1, x0:x1] - gy) ** 2) / (2 * sigma ** 2))
        heat[y0:y1, x0:x1] = np.maximum(heat[y0:y1, x0:x1], g)
        px, py = int(round(gx)), int(round(gy))
        if 0 <= px < n and 0 <= py < n:
            heat[py, px] = 1.0
            # Regression at the peak cell and its 4-neighbours.
            for ox, oy in ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)):
                qx, qy = px + ox, py + oy
                if 0 <= qx < n and 0 <= qy < n:
                    reg[0, qy, qx] = gx - qx
                    reg[1, qy, qx] = gy - qy
                    reg[2, qy, qx] = math.log(d / crater_net.DIAMETER_UNIT_PX)
                    reg_mask[qy, qx] = 1.0 if (ox, oy) == (0, 0) else 0.5
    weight[heat >= 1.0] = 1.0
    return heat, weight, reg, reg_mask


def crater_centres(heat):
    """The cells of the target heat map that are labelled crater centres (1.0, else 0.0)."""
    return (heat >= 1.0).float()


def focal_normaliser(heat):
    """What the heat-map losses are divided by: the batch's labelled crater centres, at least 1."""
    return crater_centres(heat).sum().clamp(min=1.0)


def focal_loss(pred, heat, weight):
    p = pred.clamp(1e-4, 1 - 1e-4)
    pos = crater_centres(heat)
    pos_loss = -((1 - p) ** 2) * torch.log(p) * pos
    neg_loss = -((1 - heat) ** 4) * (p ** 2) * torch.log(1 - p) * (1 - pos) * weight
    return (pos_loss.sum() + neg_loss.sum()) / focal_normaliser(heat)


def distillation_loss(pred, teacher_heat, heat):
    """Bernoulli KL divergence of the student's heat map from the teachers' mean heat map, summed
    over all cells and normalised like the focal loss: zero where they agree, also on craters
    the labels leave out (a single annotator's) or mark as ignored."""
    p = pred.clamp(1e-4, 1 - 1e-4)
    q = teacher_heat.clamp(1e-4, 1 - 1e-4)
    kl = q * torch.log(q / p) + (1 - q) * torch.log((1 - q) / (1 - p))
    return kl.sum() / focal_normaliser(heat)


class Teachers:
    """Trained models whose mean heat map the trained model also learns (knowledge distillation
    from an ensemble of earlier runs, at one network's cost at run time)."""

    def __init__(self, weight_paths):
        self.models = [crater_net.load(p) for p in weight_paths]  # in eval mode

    def heat(self, x):
        with torch.no_grad():
            return torch.stack([m(x)[:, 0:1] for m in self.models]).mean(0)


def batch(sampler, size, args):
    images, heats, weights, regs, masks = [], [], [], [], []
    for _ in range(args.batch):
        image, labels = sampler.sample()
        h, w, r, m = targets(labels, size, args.min_annotators, args.max_net_diameter)
        images.append(image[None])
        heats.append(h[None])
        weights.append(w[None])
        regs.append(r)
        masks.append(m[None])
    t = lambda a: torch.from_numpy(np.stack(a))
    return t(images), t(heats), t(weights), t(regs), t(masks)


def evaluate(model, items, min_diameter, thresholds):
    """F1 >= min_diameter on whole images, for each heat-map threshold (decoding as in C++)."""
    model.eval()
    results = {t: [0, 0, 0, 0] for t in thresholds}  # matched truth / detections, detected, truth
    with torch.no_grad():
        for _, image, craters in items:
            detections = crater_net.detect(model, image, min(thresholds))
            truth = craters[craters[:, 3] >= 2][:, :3]
            for t in thresholds:
                dets = detections[detections[:, 3] >= t]
                m, nd, nt = crater_net.score(truth, dets[:, :3], min_diameter)
                results[t][0] += m[0]
                results[t][1] += m[1]
                results[t][2] += nd
                results[t][3] += nt
    model.train()
    out = {}
    for t, (mt, md, nd, nt) in results.items():
        out[t] = crater_net.precision_recall_f1(mt, md, nd, nt)
    return out


class WeightAverage:
    """Exponential moving average of the weights and BatchNorm statistics; with decay 0 there is
    none and the raw weights stand for it."""

    def __init__(self, model, decay):
        self.decay = decay
        self.state = ({k: v.detach().clone() for k, v in model.state_dict().items()}
                      if decay > 0.0 else None)

    def update(self, model):
        if self.state is None:
            return
        with torch.no_grad():
            for k, v in model.state_dict().items():
                if v.dtype.is_floating_point:
                    self.state[k].mul_(self.decay).add_(v.detach(), alpha=1.0 - self.decay)
                else:
                    self.state[k].copy_(v)

    def weights(self, model):
        """The averaged weights, or `model`'s own without averaging."""
        return model.state_dict() if self.state is None else self.state

    def model(self, like):
        """A copy of `like` holding the averaged weights (`like` itself without averaging)."""
        if self.state is None:
            return like
        averaged = type(like)(like.channels, like.stem)
        averaged.load_state_dict(self.state)
        return averaged


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", required=True, help="the ctx-mc11e folder")
    ap.add_argument("--out", required=True, help="ONNX file to write")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--iterations", type=int, default=9000)
    ap.add_argument("--batch", type=int, default=12)
    ap.add_argument("--crop", type=int, default=160)
    ap.add_argument("--lr", type=float, default=3e-3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--min-annotators", type=int, default=2)
    ap.add_argument("--max-net-diameter", type=float, default=48.0)
    ap.add_argument("--eval-every", type=int, default=1000)
    ap.add_argument("--init", help="start from these weights (.pt) instead of random ones")
    ap.add_argument("--min-prefilter", type=float, default=0.5,
                    help="least anti-alias sigma before downsampling a crop [output px]")
    ap.add_argument("--sharpen", type=float, default=0.0,
                    help="largest unsharp-mask amount of the augmentation (0: none)")
    ap.add_argument("--generated", help="folder of generated scenes (areomap_crater_training_scenes)")
    ap.add_argument("--generated-fraction", type=float, default=0.3,
                    help="share of the crops drawn from --generated")
    ap.add_argument("--extra", action="append", default=[],
                    help="a folder of your own labelled images (NAME.png with NAME_craters.csv: "
                         "x_px,y_px,diameter_px[,annotators]) to train on as well; repeatable")
    ap.add_argument("--extra-fraction", type=float, default=0.3,
                    help="share of the crops drawn from the --extra folders")
    ap.add_argument("--validate",
                    help="a folder of labelled images (as --extra) on which the checkpoint and the "
                         "threshold are chosen instead of the held-out CTX images")
    ap.add_argument("--ema", type=float, default=0.0,
                    help="decay of an exponential moving average of the weights that is evaluated "
                         "and exported instead of the raw weights, e.g. 0.999 (0: none, as the "
                         "built-in model was trained)")
    ap.add_argument("--channels", default="12,24,32",
                    help="channels at 1/2, 1/4 and 1/8 of the input resolution")
    ap.add_argument("--stem", type=int, default=0,
                    help="channels of a 3 x 3 convolution at full resolution before the first "
                         "stride-2 one (0: none, as the built-in model)")
    ap.add_argument("--teachers", help="comma-separated trained weights (.pt) whose mean heat map "
                                       "the model also learns (distillation)")
    ap.add_argument("--distill-weight", type=float, default=1.0,
                    help="weight of the distillation loss against the labels' focal loss")
    args = ap.parse_args()

    torch.manual_seed(args.seed)
    torch.set_num_threads(args.threads)
    rng = np.random.default_rng(args.seed)
    train_letters = [c for c in ALL_IMAGES if c not in HELD_OUT]
    train = load_catalogue(args.data, train_letters)
    val = load_folder(args.validate) if args.validate else load_catalogue(args.data, HELD_OUT)
    generated = load_generated(args.generated) if args.generated else []
    extra = [item for folder in args.extra for item in load_folder(folder)]
    sampler = Sampler(train, args.crop, rng, args.min_prefilter, args.sharpen, generated,
                      args.generated_fraction, extra, args.extra_fraction)
    model = crater_net.CraterNet(tuple(int(c) for c in args.channels.split(",")), args.stem)
    if args.init:
        model = crater_net.load(args.init)
        model.train()
    print(f"parameters: {sum(p.numel() for p in model.parameters())}", flush=True)
    opt = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=args.lr, total_steps=args.iterations,
                                                pct_start=0.1)
    thresholds = [0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5]
    best = (-1.0, None, None)
    start = time.time()
    history = []
    ema = WeightAverage(model, args.ema)
    teachers = Teachers(args.teachers.split(",")) if args.teachers else None
    for it in range(1, args.iterations + 1):
        x, heat, weight, reg, mask = batch(sampler, args.crop, args)
        out = model(x)
        hm_loss = focal_loss(out[:, 0:1], heat, weight)
        if teachers is not None:
            hm_loss = hm_loss + args.distill_weight * distillation_loss(
                out[:, 0:1], teachers.heat(x), heat)
        num = mask.sum().clamp(min=1.0)
        reg_loss = ((out[:, 1:4] - reg).abs() * mask).sum() / num
        loss = hm_loss + reg_loss
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        ema.update(model)
        if it % 50 == 0:
            print(f"it {it} loss {loss.item():.3f} (heat {hm_loss.item():.3f} reg "
                  f"{reg_loss.item():.3f}) {time.time() - start:.0f} s", flush=True)
        if it % args.eval_every == 0 or it == args.iterations:
            scores = evaluate(ema.model(model), val, 8.0, thresholds)
            t_best = max(scores, key=lambda t: scores[t][2])
            p, r, f1 = scores[t_best]
            history.append({"iteration": it, "threshold": t_best, "precision": p, "recall": r,
                            "f1": f1})
            print(f"val it {it}: best threshold {t_best} P {p:.3f} R {r:.3f} F1 {f1:.3f}",
                  flush=True)
            if f1 > best[0]:
                best = (f1, t_best, {k: v.clone() for k, v in ema.weights(model).items()})
    model = crater_net.CraterNet(model.channels, model.stem)
    model.load_state_dict(best[2])
    model.eval()
    crater_net.export_onnx(model, args.out)
    meta = {"threshold": best[1], "validation_f1": best[0], "history": history,
            "seconds": time.time() - start, "seed": args.seed, "args": vars(args),
            "held_out": list(HELD_OUT), "validated_on": args.validate or "ctx-mc11e held out"}
    with open(os.path.splitext(args.out)[0] + ".train.json", "w") as f:
        json.dump(meta, f, indent=1)
    torch.save(best[2], os.path.splitext(args.out)[0] + ".pt")
    print(json.dumps({k: meta[k] for k in ("threshold", "validation_f1", "seconds")}))


if __name__ == "__main__":
    main()
