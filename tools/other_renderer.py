#!/usr/bin/env python3
"""Another renderer of MARVIN's scenes, for a developer's check of vision off the cell's own images.

It shares no code with `sim`'s renderer: it takes the geometry alone (the depth and id maps and
scene.json that `marvin render` writes of a world whose cameras are N times finer) and forms
the 512x512 pair its own way: surface normals from the depth, a spot lamp with fall-off and a
fill lamp, ambient light from above, Blinn-Phong highlights, each part's albedo off the
library's by up to +-15%, a table textured in world coordinates, shadows marched through
both cameras' depth maps, each pixel integrated over its N x N samples, a Gaussian lens blur, vignetting,
and sensors of their own (shot and read noise, fixed-pattern gain, gains, black levels and
response curves that differ between the two cameras).

Usage (the fine world: a copy of the world with each camera's `resolution = [2048, 2048]` and
`focal_px = 4000.0`, its `urdf` path still reaching the URDF):
    marvin render <world> --seed S --scenes K --out SCENES        # each scene's truth, SCENES/<seed>/
    marvin render <fine world> --seed S --scenes K --out FINE
    python3 tools/other_renderer.py FINE/<seed> SCENES/<seed> [--variant mild|harsh] [--set k=json]

writes SCENES/<seed>/left.png and right.png over the cell's own (keep a copy to compare). Then
`marvin eval pairs SCENES --cameras cameras.json` reads every scene as a user's pair.
Needs numpy, scipy and Pillow; it is not part of the project's build or tests.
"""

import argparse
import json
import os
import re

import numpy as np
from PIL import Image
from scipy.ndimage import gaussian_filter, maximum_filter, minimum_filter

HERE = os.path.dirname(os.path.abspath(__file__))
ARM_ID_BASE = 1000

VARIANTS = {
    # Each camera: blur sigma (output px), gain, black level (DN), response exponent,
    # full well (e-), read noise (e-), fixed-pattern gain spread, vignetting exponent.
    "mild": {
        "key": {"position": [0.45, -0.35, 0.95], "power": 0.80, "cone_exp": 3.0},
        "fill": {"position": [-0.55, 0.25, 1.40], "power": 0.25},
        "ambient": 0.12,
        "gloss": {"parts": 0.12, "table": 0.03, "shininess": 40.0},
        "albedo_spread": 0.15,
        "texture": 0.12,
        "cameras": {
            "left": {"blur": 0.60, "gain": 1.00, "black": 5.0, "response": 0.90, "well": 12000.0,
                     "read": 10.0, "prnu": 0.015, "vignetting": 3.5},
            "right": {"blur": 0.75, "gain": 1.10, "black": 12.0, "response": 1.00, "well": 12000.0,
                      "read": 12.0, "prnu": 0.015, "vignetting": 3.0},
        },
    },
    "harsh": {
        "key": {"position": [0.35, -0.45, 0.80], "power": 0.70, "cone_exp": 6.0},
        "fill": {"position": [-0.60, 0.10, 1.20], "power": 0.15},
        "ambient": 0.08,
        "gloss": {"parts": 0.25, "table": 0.05, "shininess": 25.0},
        "albedo_spread": 0.15,
        "texture": 0.20,
        "cameras": {
            "left": {"blur": 0.80, "gain": 0.92, "black": 3.0, "response": 0.45, "well": 8000.0,
                     "read": 20.0, "prnu": 0.02, "vignetting": 4.0},
            "right": {"blur": 0.95, "gain": 1.08, "black": 16.0, "response": 0.80, "well": 8000.0,
                      "read": 25.0, "prnu": 0.02, "vignetting": 3.0},
        },
    },
}


def library_albedos():
    albedo = {}
    folder = os.path.join(HERE, "..", "mesh", "models")
    for name in os.listdir(folder):
        if name.endswith(".toml"):
            text = open(os.path.join(folder, name)).read()
            m = re.search(r"^albedo\s*=\s*([0-9.]+)", text, re.M)
            if m:
                albedo[name[:-5]] = float(m.group(1))
    return albedo


def quat_matrix(q):
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def undistort(xd, yd, d):
    """Normalised distorted coordinates to undistorted ones (plumb bob, by fixed-point iteration)."""
    x, y = xd.copy(), yd.copy()
    for _ in range(12):
        r2 = x * x + y * y
        radial = 1 + d["k1"] * r2 + d["k2"] * r2 * r2 + d["k3"] * r2 ** 3
        dx = 2 * d["p1"] * x * y + d["p2"] * (r2 + 2 * x * x)
        dy = d["p1"] * (r2 + 2 * y * y) + 2 * d["p2"] * x * y
        x, y = (xd - dx) / radial, (yd - dy) / radial
    return x, y


def distort(x, y, d):
    r2 = x * x + y * y
    radial = 1 + d["k1"] * r2 + d["k2"] * r2 * r2 + d["k3"] * r2 ** 3
    return (x * radial + 2 * d["p1"] * x * y + d["p2"] * (r2 + 2 * x * x),
            y * radial + d["p1"] * (r2 + 2 * y * y) + 2 * d["p2"] * x * y)


class Camera:
    def __init__(self, built):
        p = built["pinhole"]
        self.w, self.h = p["width"], p["height"]
        self.fx, self.fy, self.cx, self.cy = p["fx"], p["fy"], p["cx"], p["cy"]
        pose = p["world_from_cam"]
        self.R = quat_matrix(pose["rotation_xyzw"])
        self.t = np.array(pose["translation_m"])
        self.dist = built["lens"]["distortion"]

    def points(self, depth):
        """World points (H, W, 3) of a depth map along the optical axis (0: none)."""
        v, u = np.mgrid[0:self.h, 0:self.w].astype(np.float64)
        x, y = undistort((u - self.cx) / self.fx, (v - self.cy) / self.fy, self.dist)
        cam = np.stack([x * depth, y * depth, depth], axis=-1)
        return cam @ self.R.T + self.t

    def project(self, world):
        """Pixel coordinates and depth of world points (..., 3)."""
        cam = (world - self.t) @ self.R
        z = cam[..., 2]
        xd, yd = distort(cam[..., 0] / z, cam[..., 1] / z, self.dist)
        return self.fx * xd + self.cx, self.fy * yd + self.cy, z


def normals(P, valid, cam_centre, step=4):
    """Unit normals from the world points: along each axis the difference over `step` pixels on
    the side where the surface runs straighter (so a crease or a depth step takes the face's own)."""
    def axis_diff(axis):
        fwd = np.roll(P, -step, axis=axis) - P
        bwd = P - np.roll(P, step, axis=axis)
        fwd_bend = np.linalg.norm(np.roll(P, -2 * step, axis=axis) - 2 * np.roll(P, -step, axis=axis) + P, axis=-1)
        bwd_bend = np.linalg.norm(P - 2 * np.roll(P, step, axis=axis) + np.roll(P, 2 * step, axis=axis), axis=-1)
        fwd_ok = np.roll(valid, -step, axis=axis) & np.roll(valid, -2 * step, axis=axis)
        bwd_ok = np.roll(valid, step, axis=axis) & np.roll(valid, 2 * step, axis=axis)
        fwd_bend = np.where(fwd_ok, fwd_bend, np.inf)
        bwd_bend = np.where(bwd_ok, bwd_bend, np.inf)
        return np.where((fwd_bend <= bwd_bend)[..., None], fwd, bwd)
    n = np.cross(axis_diff(1), axis_diff(0))
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    towards = cam_centre - P
    flip = np.sum(n * towards, axis=-1) < 0
    n[flip] *= -1
    return n


def value_noise(xy, scale, rng_seed):
    """Smooth noise in [-1, 1] over world (x, y) metres, cells of `scale` metres."""
    rng = np.random.default_rng(rng_seed)
    grid = rng.uniform(-1, 1, size=(256, 256))
    gx, gy = xy[..., 0] / scale + 128, xy[..., 1] / scale + 128
    x0, y0 = np.floor(gx).astype(int), np.floor(gy).astype(int)
    fx, fy = gx - x0, gy - y0
    fx, fy = fx * fx * (3 - 2 * fx), fy * fy * (3 - 2 * fy)
    g = lambda a, b: grid[np.clip(b, 0, 255), np.clip(a, 0, 255)]
    return (g(x0, y0) * (1 - fx) * (1 - fy) + g(x0 + 1, y0) * fx * (1 - fy)
            + g(x0, y0 + 1) * (1 - fx) * fy + g(x0 + 1, y0 + 1) * fx * fy)


def march(points, views):
    """For world points (N, 3): whether a march from each towards the key lamp meets, in both
    cameras' depth maps, a surface in front of the march's point (within a part's thickness).
    Asking both cameras makes it a function of the point alone, so the two images' shadows agree."""
    dirn = views["lamp"] - points
    dirn /= np.linalg.norm(dirn, axis=-1, keepdims=True)
    hit = np.zeros(len(points), bool)
    for s in np.arange(0.003, 0.15, 0.002):
        q = points + dirn * s
        behind = np.ones(len(points), bool)
        for cam, depth in views["cameras"]:
            u, v, z = cam.project(q)
            ui, vi = np.round(u).astype(int), np.round(v).astype(int)
            inside = (ui >= 0) & (vi >= 0) & (ui < cam.w) & (vi < cam.h)
            d = depth[np.clip(vi, 0, cam.h - 1), np.clip(ui, 0, cam.w - 1)]
            behind &= inside & (d > 0) & (d < z - 0.002) & (d > z - 0.06)
        hit |= behind
    return hit


def shadowed(P, valid, views, k=4):
    """The key lamp's shadow mask at every fine sample: marched once a k x k block (at its
    middle), then again at every sample of the blocks where the mask changes, so that a shadow's
    edge, and a face turned from the lamp, end where the geometry puts them."""
    h, w = P.shape[0] // k, P.shape[1] // k
    coarse = march(P[k // 2::k, k // 2::k].reshape(-1, 3), views).reshape(h, w)
    mixed = maximum_filter(coarse, size=3) != minimum_filter(coarse, size=3)
    mask = np.repeat(np.repeat(coarse, k, axis=0), k, axis=1)
    fine = np.nonzero(np.repeat(np.repeat(mixed, k, axis=0), k, axis=1))
    mask[fine] = march(P[fine], views)
    return mask & valid


def penumbra(mask, ids, sigma):
    """The hard mask blurred by `sigma` fine samples within each surface (normalised
    convolution per id), so that a shadow's soft edge does not spill onto the part casting it."""
    out = np.zeros(mask.shape)
    for i in np.unique(ids):
        here = ids == i
        ys, xs = np.nonzero(here)
        m = int(4 * sigma) + 1
        y0, y1 = max(ys.min() - m, 0), min(ys.max() + m + 1, mask.shape[0])
        x0, x1 = max(xs.min() - m, 0), min(xs.max() + m + 1, mask.shape[1])
        h = here[y0:y1, x0:x1].astype(np.float64)
        num = gaussian_filter(mask[y0:y1, x0:x1] * h, sigma)
        den = gaussian_filter(h, sigma)
        out[y0:y1, x0:x1][here[y0:y1, x0:x1]] = (num / np.maximum(den, 1e-9))[here[y0:y1, x0:x1]]
    return out


def load_view(fine_dir, side, scene):
    cam = Camera(scene["as_built"][side])
    depth = np.asarray(Image.open(os.path.join(fine_dir, f"depth_{side}.png")), dtype=np.float64) * scene["depth_unit_m"]
    ids = np.asarray(Image.open(os.path.join(fine_dir, f"ids_{side}.png")), dtype=np.int64)
    return cam, depth, ids


def radiance(view, both, scene, v, albedos, seed):
    cam, depth, ids = view
    valid = depth > 0
    P = cam.points(depth)
    n = normals(P, valid, cam.t)
    # Albedo: each part off its library value, the table and the rest textured in the world.
    rng = np.random.default_rng(seed * 7919 + 11)
    xy = P[..., :2]
    tex = (0.55 * value_noise(xy, 0.040, seed) + 0.30 * value_noise(xy, 0.008, seed + 1)
           + 0.15 * value_noise(xy, 0.0025, seed + 2))
    albedo = 0.3 * (1 + v["texture"] * tex)
    gloss = np.full(depth.shape, v["gloss"]["table"])
    for o in scene["objects"]:
        a = albedos.get(o["model"], 0.7) * (1 + rng.uniform(-v["albedo_spread"], v["albedo_spread"]))
        here = ids == o["id"]
        albedo[here] = a
        gloss[here] = v["gloss"]["parts"]
    albedo[ids >= ARM_ID_BASE] = 0.25
    # Light: the key lamp (spot, aimed at the origin, falling off with distance), a fill lamp,
    # ambient from above.
    key = np.array(v["key"]["position"])
    view = cam.t - P
    view /= np.maximum(np.linalg.norm(view, axis=-1, keepdims=True), 1e-12)
    total = v["ambient"] * (0.6 + 0.4 * np.clip(n[..., 2], 0, 1)) * albedo
    views = {"lamp": key, "cameras": [(c, d) for c, d, _ in both]}
    # A face turned from the key lamp is dark by its own shading: only shadows cast on faces
    # the lamp would light are masked, and their penumbra lies on the surface they fall on.
    to_key = key - P
    facing = np.sum(n * to_key, axis=-1) > 0
    lit = 1.0 - penumbra(shadowed(P, valid, views) & facing, ids, 3.0)
    for lamp, shade in ((v["key"], lit), (v["fill"], 1.0)):
        pos = np.array(lamp["position"])
        to = pos - P
        d = np.linalg.norm(to, axis=-1, keepdims=True)
        l = to / d
        irradiance = lamp["power"] * (np.linalg.norm(pos) / d[..., 0]) ** 2
        if "cone_exp" in lamp:
            axis = -pos / np.linalg.norm(pos)
            irradiance *= np.clip(np.sum(-l * axis, axis=-1), 0, 1) ** lamp["cone_exp"]
        ndl = np.clip(np.sum(n * l, axis=-1), 0, 1)
        half = l + view
        half /= np.maximum(np.linalg.norm(half, axis=-1, keepdims=True), 1e-12)
        spec = np.clip(np.sum(n * half, axis=-1), 0, 1) ** v["gloss"]["shininess"] * (ndl > 0)
        total += shade * irradiance * ((1 - gloss) * albedo * ndl + gloss * spec * 3.0)
    total[~valid] = 0.0
    return total, cam


def sense(rad_fine, cam_fine, factor, c, rng):
    """The fine radiance integrated over each output pixel, blurred, vignetted and sensed."""
    blurred = gaussian_filter(rad_fine, c["blur"] * factor)
    h, w = rad_fine.shape[0] // factor, rad_fine.shape[1] // factor
    img = blurred.reshape(h, factor, w, factor).mean(axis=(1, 3))
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    fx = cam_fine.fx / factor
    cx, cy = (cam_fine.cx - (factor - 1) / 2) / factor, (cam_fine.cy - (factor - 1) / 2) / factor
    cos = 1 / np.sqrt(1 + ((u - cx) ** 2 + (v - cy) ** 2) / fx ** 2)
    img = img * cos ** c["vignetting"]
    prnu = 1 + c["prnu"] * rng.standard_normal((h, w))
    electrons = rng.poisson(np.clip(img * prnu * c["well"] * 0.85, 0, None)).astype(np.float64)
    electrons += c["read"] * rng.standard_normal((h, w))
    signal = np.clip(c["gain"] * electrons / c["well"], 0, 1) ** c["response"]
    return np.clip(np.round(signal * (255 - c["black"]) + c["black"]), 0, 255).astype(np.uint8)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("fine", help="marvin render output of the N-times-finer world")
    ap.add_argument("scene", help="marvin render output of the world itself; left/right.png replaced")
    ap.add_argument("--variant", default="mild", choices=sorted(VARIANTS))
    ap.add_argument("--set", action="append", default=[], metavar="KEY=JSON",
                    help="override one setting of the variant, e.g. key.position=[-0.4,-0.6,1.0] or texture=0")
    args = ap.parse_args()
    fine = json.load(open(os.path.join(args.fine, "scene.json")))
    own = json.load(open(os.path.join(args.scene, "scene.json")))
    if [o["world_from_model"] for o in fine["objects"]] != [o["world_from_model"] for o in own["objects"]]:
        raise SystemExit(f"{args.fine} and {args.scene} are not the same scene")
    factor = fine["as_built"]["left"]["pinhole"]["width"] // own["as_built"]["left"]["pinhole"]["width"]
    v = json.loads(json.dumps(VARIANTS[args.variant]))
    for item in args.set:
        key, value = item.split("=", 1)
        *path, last = key.split(".")
        node = v
        for k in path:
            node = node[k]
        if last not in node:
            raise SystemExit(f"--set {item}: no setting `{key}` in variant {args.variant}")
        node[last] = json.loads(value)
    albedos = library_albedos()
    seed = int(own["seed"])
    both = [load_view(args.fine, side, fine) for side in ("left", "right")]
    for k, side in enumerate(("left", "right")):
        rad, cam = radiance(both[k], both, fine, v, albedos, seed)
        rng = np.random.default_rng(seed * 31 + k)
        img = sense(rad, cam, factor, v["cameras"][side], rng)
        Image.fromarray(img).save(os.path.join(args.scene, f"{side}.png"))


if __name__ == "__main__":
    main()
